//! Properties taken from the property language (models/alsomitra/alsomitra.spec) agree
//! with the trainer's built-in P1-P4 (`case_study`): same preconditions, same verdicts on
//! the output, at random points, in the trainer's own units.

use rand::{Rng, SeedableRng};
use samara_spec::{Bindings, Spec};
use samara_train::{case_study, from_query, read_table, rescale_query, MinMax, Units};
use std::path::Path;

#[test]
fn spec_properties_match_the_built_in_ones() {
    let data = read_table(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/reference/Training_Data.csv"
    )))
    .unwrap();
    let mm = MinMax::of(&data);
    let spec = Spec::read(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/alsomitra/alsomitra.spec"
    )))
    .unwrap();
    let decl = &spec.networks[0];
    let inputs: Vec<(f64, f64)> = (0..6)
        .map(|k| {
            let (c, s) = decl.input_map(k);
            (mm.range[k] / s, (mm.min[k] - c) / s)
        })
        .collect();
    let (oc, os) = decl.output_map(0);
    let outputs = [(mm.range[6] / os, (mm.min[6] - oc) / os)];
    let units = Units {
        c: mm.min[..6].to_vec(),
        s: mm.range[..6].to_vec(),
        c_out: mm.min[6],
        s_out: mm.range[6],
    };
    // The built-in properties use the spec's domain box (raw) for a fair comparison.
    let lo: Vec<f64> = decl.domain.iter().map(|d| d.0).collect();
    let hi: Vec<f64> = decl.domain.iter().map(|d| d.1).collect();
    let mut b = Bindings::default();
    b.params.insert("ystar".into(), 2.0);
    let builtin = case_study(&units, &lo, &hi, 2.0);
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for (k, name) in ["p1", "p2", "p3", "p4"].iter().enumerate() {
        let q = rescale_query(
            &spec.lower_prove(name, &b).unwrap()[0].query,
            &inputs,
            &outputs,
        );
        let props = from_query(&q).unwrap();
        let bi = &builtin[k];
        let mut checked = 0;
        for _ in 0..5000 {
            let z: Vec<f64> = (0..6).map(|_| r.gen_range(-0.2..1.2)).collect();
            let o = r.gen_range(-0.5..1.5);
            let pre_spec = props
                .iter()
                .filter(|p| p.region.contains(&z, 0.0))
                .collect::<Vec<_>>();
            let in_bi = bi.region.contains(&z, 0.0);
            // Skip points on a boundary within rounding.
            if props.iter().any(|p| {
                (p.region.contains(&z, 1e-9) != p.region.contains(&z, -1e-9))
                    || (bi.region.contains(&z, 1e-9) != bi.region.contains(&z, -1e-9))
            }) {
                continue;
            }
            // The built-in property is violated iff some spec disjunct is violated.
            let viol_bi = in_bi && !bi.formula.holds(o);
            let viol_spec = pre_spec.iter().any(|p| !p.formula.holds(o));
            if (o - 0.5).abs() > 1e-6 {
                assert_eq!(viol_bi, viol_spec, "{name} at {z:?} out {o}");
                checked += 1;
            }
        }
        assert!(checked > 4000);
    }
}
