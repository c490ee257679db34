//! Times [`samara_bounds::search::solve`] on a query dumped as text (maps, then cases).
use samara_bounds::search::{self, Case, OutputConstraint, Settings};
use samara_bounds::symbolic::Objective;
use samara_nn::Affine;
use samara_num::Timeout;
use std::time::Instant;

fn main() {
    let path = std::env::args().nth(1).expect("file");
    let txt = std::fs::read_to_string(path).expect("read");
    let mut lines = txt.lines();
    let nums = |l: &str| -> Vec<f64> { l.split_whitespace().map(|v| v.parse().unwrap()).collect() };
    let nm: usize = lines.next().unwrap().trim().parse().unwrap();
    let mut maps = Vec::new();
    for _ in 0..nm {
        let h = nums(lines.next().unwrap());
        let (inp, out, r) = (h[0] as usize, h[1] as usize, h[2] != 0.0);
        let w = nums(lines.next().unwrap());
        let b = nums(lines.next().unwrap());
        maps.push((Affine { inp, out, w, b }, r));
    }
    let nc: usize = lines.next().unwrap().trim().parse().unwrap();
    let mut cases = Vec::new();
    for _ in 0..nc {
        let lo = nums(lines.next().unwrap());
        let hi = nums(lines.next().unwrap());
        let k: usize = lines.next().unwrap().trim().parse().unwrap();
        let mut constraints = Vec::new();
        for _ in 0..k {
            let v = nums(lines.next().unwrap());
            let no = v.len() - 2;
            constraints.push(OutputConstraint {
                obj: Objective {
                    c: v[..no].to_vec(),
                    d: v[no],
                },
                strict: v[no + 1] != 0.0,
            });
        }
        cases.push(Case {
            lo,
            hi,
            constraints,
        });
    }
    // SAMARA_PHASE_MAX_UNSTABLE overrides the setting (for tuning).
    let phase_max_unstable = std::env::var("SAMARA_PHASE_MAX_UNSTABLE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(Settings::default().phase_max_unstable);
    let s = Settings {
        phase_max_unstable,
        timeout: Timeout::from_secs_f64(200.0).unwrap(),
        ..Default::default()
    };
    let t0 = Instant::now();
    let (o, st) = search::solve(&maps, &cases, &s);
    println!(
        "{:?} pieces {} in {:.2} s",
        matches!(o, samara_num::Outcome::Proved),
        st.pieces,
        t0.elapsed().as_secs_f64()
    );
}
