//! The built-in plate glider as the system language describes it: each variant is the
//! system file shipped beside the case study (`examples/archcomp/alsomitra_*.sys`, which
//! re-express `samara-plant`'s models operation for operation), compiled from its
//! source. The property language's closed loops (`samara-spec`) name a variant, check
//! their `start` and network against its [`System`] (its states, what its controller
//! observes), so neither language needs the plant crate: samara-plant stays a
//! consumer's choice (the published glider engines of reach and training map a
//! [`Variant`] to its model by name).

use crate::System;

/// A variant of the plate, by the name closed loops and `--model` give it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Variant {
    /// With the filter state `E` (`plate6`).
    Plate6,
    /// Six states, no filter (`reduced`, the published reach setting).
    Reduced,
    /// With the filter state and the full drag model (`full`).
    Full,
}

impl Variant {
    /// Every variant, in the order messages list them.
    pub const ALL: [Variant; 3] = [Variant::Plate6, Variant::Reduced, Variant::Full];

    /// Its name: `plate6`, `reduced` or `full`.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Plate6 => "plate6",
            Variant::Reduced => "reduced",
            Variant::Full => "full",
        }
    }

    /// The variant named `s`.
    pub fn from_name(s: &str) -> Option<Variant> {
        Variant::ALL.into_iter().find(|v| v.name() == s)
    }

    /// The text of its system file.
    pub fn source(self) -> &'static str {
        match self {
            Variant::Plate6 => {
                include_str!("../../../examples/archcomp/alsomitra_plate6.sys")
            }
            Variant::Reduced => {
                include_str!("../../../examples/archcomp/alsomitra_reduced.sys")
            }
            Variant::Full => include_str!("../../../examples/archcomp/alsomitra_full.sys"),
        }
    }

    /// Its system, compiled from [`Variant::source`] (named
    /// `examples/archcomp/alsomitra_NAME.sys` in messages).
    pub fn system(self) -> System {
        let file = format!("examples/archcomp/alsomitra_{}.sys", self.name());
        System::parse(self.source(), &file)
            .unwrap_or_else(|e| panic!("the shipped system file {file} compiles: {e}"))
    }
}

/// The states of variant `v`, in its order (the six physical states, then the filter
/// state `E` where the variant has one).
pub fn states(v: Variant) -> Vec<String> {
    v.system().states
}

/// What a controller of the plate reads: the six physical states, in order (the
/// `observe` line of every variant's file).
pub fn controller_inputs() -> Vec<String> {
    Variant::Reduced.system().states
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
        assert_eq!(states(Variant::Reduced), controller_inputs());
        for v in [Variant::Plate6, Variant::Full] {
            assert_eq!(states(v)[..6], *controller_inputs());
            assert_eq!(states(v)[6..], ["E"]);
        }
        for v in Variant::ALL {
            let sys = v.system();
            assert_eq!(Variant::from_name(v.name()), Some(v));
            // The controller observes the six physical states and sets `ex`.
            assert_eq!(
                (sys.n_observed(), sys.n_net_outputs),
                (6, 1),
                "{}",
                v.name()
            );
            assert_eq!(sys.inputs, [ACTUATION], "{}", v.name());
        }
        // The same variants as the plant crate's models, with as many states.
        for m in samara_plant::Model::ALL {
            let v = Variant::from_name(m.name()).expect("a variant per model");
            assert_eq!(states(v).len(), m.dim(), "{}", m.name());
        }
        assert_eq!(Variant::ALL.len(), samara_plant::Model::ALL.len());
    }
}
