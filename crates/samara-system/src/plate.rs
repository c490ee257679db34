//! The built-in plate glider (`samara-plant`) described as the system language describes
//! a plant: its variants by name, its states in order, what its controller reads and the
//! input it sets. The property language's closed loops (`samara-spec`) check their
//! `model`, `start` and network against this description, so the languages see one plant
//! description and the property language needs no plant crate of its own.

pub use samara_plant::Model;

/// The states of the plate's variant `model`, in its order (`model.dim()` names: the six
/// physical states, then the filter state `E` where the variant has one).
pub fn states(model: Model) -> &'static [&'static str] {
    &samara_plant::STATE_NAMES[..model.dim()]
}

/// What a controller of the plate reads: the six physical states, in order.
pub fn controller_inputs() -> &'static [&'static str] {
    &samara_plant::STATE_NAMES[..6]
}

/// The plate's one input, the actuation the controller sets.
pub const ACTUATION: &str = "ex";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variants_name_their_states_in_order() {
        // docs/MODEL.md: s = (v_xp, v_yp, omega, theta, x, y [, E]), E in plate6 and full
        // only.
        assert_eq!(
            controller_inputs(),
            ["v_xp", "v_yp", "omega", "theta", "x", "y"]
        );
        assert_eq!(states(Model::Reduced), controller_inputs());
        for m in [Model::Plate6, Model::Full] {
            assert_eq!(states(m)[..6], *controller_inputs());
            assert_eq!(states(m)[6..], ["E"]);
        }
    }
}
