//! P1-P4 as `models/alsomitra/alsomitra.spec` states them, lowered to critical queries
//! for the tests (`highs_crosscheck.rs`).

/// P1-P4 of models/alsomitra/alsomitra.spec as critical queries of `ystar` (P1, P2 hold
/// above the supremum, P3, P4 below the infimum), for a network in the spec's units or,
/// with `raw`, one taking raw inputs and giving raw outputs.
pub fn p1_to_p4(raw: bool) -> Vec<samara_spec::normal::Query> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../models/alsomitra/alsomitra.spec");
    let mut spec = samara_spec::Spec::read(&path).unwrap();
    if raw {
        spec.networks[0].in_norm = None;
        spec.networks[0].out_norm = None;
    }
    ["p1", "p2", "p3", "p4"]
        .iter()
        .map(|p| {
            let mut q = spec
                .lower_critical(p, "ystar", &samara_spec::Bindings::default())
                .unwrap()
                .remove(0)
                .query;
            if let samara_spec::normal::Goal::Optimise { sense, .. } = &mut q.goal {
                if *p == "p3" || *p == "p4" {
                    *sense = samara_spec::normal::Sense::Min;
                }
            }
            q
        })
        .collect()
}
