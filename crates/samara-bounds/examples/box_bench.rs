//! Times [`samara_bounds::search::solve`] on queries dumped as text (maps, then cases) by
//! `bench/vnncomp/dump_box.py`: one line per file (outcome, pieces, seconds), then the sum.
//! Tuning overrides from the environment: `SAMARA_PHASE_MAX_UNSTABLE`,
//! `SAMARA_ATTACK_SECONDS`, `SAMARA_LOOK_REFINE`, `SAMARA_ALPHA_ITERS`.
use samara_bounds::search::{self, Case, OutputConstraint, Settings};
use samara_bounds::symbolic::Objective;
use samara_nn::Affine;
use samara_num::Timeout;
use std::time::Instant;

fn main() {
    let mut total = 0.0;
    let c0 = cpu_seconds();
    let files: Vec<String> = std::env::args().skip(1).collect();
    for path in &files {
        total += run(path);
    }
    if files.len() > 1 {
        println!(
            "{} files in {total:.2} s, cpu {:.2} s",
            files.len(),
            cpu_seconds() - c0
        );
    }
}

/// The process's user + system CPU seconds, every thread (`/proc/self/stat`, in clock
/// ticks of 10 ms; 0 where it cannot be read).
fn cpu_seconds() -> f64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let rest = s.rsplit_once(')').map_or("", |r| r.1);
    let f: Vec<f64> = rest
        .split_whitespace()
        .filter_map(|v| v.parse().ok())
        .collect();
    // The numbers after the command's ")" (the state is not one): utime is the 11th.
    f.get(10)
        .zip(f.get(11))
        .map_or(0.0, |(u, s)| (u + s) / 100.0)
}

/// One query file: prints its line and returns its seconds.
fn run(path: &str) -> f64 {
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
        maps.push((Affine::new(inp, out, w, b), r));
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
    fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    }
    let d = Settings::default();
    let s = Settings {
        phase_max_unstable: env("SAMARA_PHASE_MAX_UNSTABLE", d.phase_max_unstable),
        attack_seconds: env("SAMARA_ATTACK_SECONDS", d.attack_seconds),
        look_refine: env("SAMARA_LOOK_REFINE", d.look_refine),
        alpha_iters: env("SAMARA_ALPHA_ITERS", d.alpha_iters),
        timeout: Timeout::from_secs_f64(200.0).unwrap(),
        ..Default::default()
    };
    let t0 = Instant::now();
    let c0 = cpu_seconds();
    let (o, st) = search::solve(&maps, &cases, &s);
    let secs = t0.elapsed().as_secs_f64();
    let cpu = cpu_seconds() - c0;
    let name = std::path::Path::new(path).file_name().unwrap_or_default();
    let verdict = match o {
        samara_num::Outcome::Proved => "unsat".to_string(),
        samara_num::Outcome::Violated(_) => "sat".to_string(),
        samara_num::Outcome::Unknown(r) => format!("unknown ({r:?})"),
    };
    println!(
        "{} {verdict} pieces {} in {secs:.3} s, cpu {cpu:.2} s",
        name.to_string_lossy(),
        st.pieces
    );
    secs
}
