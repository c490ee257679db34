//! The plant's equations run unchanged on intervals and enclose the f64 right-hand side
//! at every sampled point of the box, for all three variants (the full model's branches
//! become hulls when a mask edge falls inside the box).

use rand::{Rng, SeedableRng};
use samara_num::Interval;
use samara_plant::{Model, Plant};

#[test]
fn interval_rhs_encloses_point_rhs() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(12);
    for model in Model::ALL {
        let p = Plant::new(model);
        let n = p.dim();
        for case in 0..200 {
            // Boxes around flight states; some straddle alpha = 0 (v_yp around 0) and omega = 0.
            let centre = [
                r.gen_range(0.9..1.4),
                r.gen_range(-0.5..0.2),
                r.gen_range(-0.4..0.4),
                r.gen_range(-1.0..0.2),
                r.gen_range(0.0..40.0),
                r.gen_range(-40.0..5.0),
                r.gen_range(-0.1..0.1),
            ];
            let w = if case % 3 == 0 { 0.05 } else { 0.005 };
            let bx: Vec<Interval> = centre[..n]
                .iter()
                .map(|c| Interval::new(c - w, c + w))
                .collect();
            let ex = Interval::new(0.185, 0.186);
            let mut out = vec![Interval::point(0.0); n];
            p.rhs(&bx, &ex, &mut out);
            for _ in 0..50 {
                let s: Vec<f64> = bx.iter().map(|i| r.gen_range(i.lo..=i.hi)).collect();
                let e = r.gen_range(0.185..=0.186);
                let mut d = vec![0.0; n];
                p.rhs(&s, &e, &mut d);
                for k in 0..n {
                    assert!(
                        out[k].contains(d[k]),
                        "{model:?} component {k}: {} not in {:?}",
                        d[k],
                        out[k]
                    );
                }
            }
        }
    }
}
