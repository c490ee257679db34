//! Standing fuzz suite of the numeric flags of `samara simulate` and `samara reach`
//! (issue 17): the built binary runs on random and extreme values of one flag at a time
//! (the other flags at small settings, so valid runs are quick) and must exit with 0, 1
//! or 2 — never a panic (101), an abort (134) or a signal — within 20 s per run (a
//! longer run is killed and counted as a hang). A run refused with exit code 2 must leave
//! no output folder behind, and stderr never shows a panic.
//!
//! Values: an extreme list per flag type (NaN, infinities, -0, 1e308, 5e-324, 2^64,
//! negative, empty, text, ...) and random numbers (log-uniform magnitude, random sign;
//! the magnitude range per flag keeps valid runs small: valid values beyond it are
//! covered by the extreme list and the regression tests).
//!
//! CI runs a few cases per flag; `cargo test --release -p samara-cli --test
//! cliio_fuzz_flags -- --ignored --nocapture` runs many more and prints the counts.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

use crate::support;
use support::{reference, samara};

const TIMEOUT: Duration = Duration::from_secs(20);

const EXTREME_FLOATS: &[&str] = &[
    "nan",
    "NaN",
    "inf",
    "-inf",
    "+inf",
    "infinity",
    "-0",
    "0",
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "1e-300",
    "-1e-300",
    "5e-324",
    "18446744073709551616",
    "-1",
    "1",
    "",
    "abc",
    "0x10",
    "1e",
    "--",
    "2.5.3",
    " 1",
    "1e400",
];

const EXTREME_INTS: &[&str] = &[
    "0",
    "-1",
    "1",
    "2",
    "-0",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999",
    "1e3",
    "nan",
    "",
    "+3",
    "1.5",
    "100000",
    "100001",
    "1025",
    "1024",
];

fn random_float(rng: &mut ChaCha8Rng, lo_exp: f64, hi_exp: f64) -> String {
    match rng.gen_range(0..10) {
        0..=2 => EXTREME_FLOATS[rng.gen_range(0..EXTREME_FLOATS.len())].to_string(),
        3 => ["0.5", "0.25", "0.1", "0.05", "0.01", "0.001", "1", "2"][rng.gen_range(0..8)]
            .to_string(),
        _ => {
            let m = 10f64.powf(rng.gen_range(lo_exp..hi_exp));
            let v = if rng.gen_bool(0.2) { -m } else { m };
            if rng.gen_bool(0.5) {
                format!("{v}")
            } else {
                format!("{v:e}")
            }
        }
    }
}

fn random_int(rng: &mut ChaCha8Rng, max_exp: u32) -> String {
    if rng.gen_bool(0.4) {
        EXTREME_INTS[rng.gen_range(0..EXTREME_INTS.len())].to_string()
    } else {
        let e = rng.gen_range(0..=max_exp);
        rng.gen_range(0..10u64.pow(e)).to_string()
    }
}

fn random_interval(rng: &mut ChaCha8Rng) -> String {
    let a = random_float(rng, -6.0, 4.0);
    match rng.gen_range(0..6) {
        0 => a,
        1 => format!(
            "{a}:{}:{}",
            random_float(rng, -6.0, 4.0),
            random_float(rng, -6.0, 4.0)
        ),
        2 => {
            // A narrow, probably valid interval.
            let x: f64 = rng.gen_range(-3.0..5.0);
            format!("{x}:{}", x + 10f64.powf(rng.gen_range(-6.0..0.0)))
        }
        _ => format!("{a}:{}", random_float(rng, -6.0, 4.0)),
    }
}

#[derive(Default)]
struct Counts {
    runs: usize,
    by_code: [usize; 3],
    max_ms: f64,
}

/// Run `samara` with `args` + `--out`, in a fresh temporary folder; check the exit code,
/// the time, stderr and (on exit 2) that no output folder was left.
fn run_case(args: &[String], counts: &mut Counts) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("new").join("out");
    let err_path = dir.path().join("stderr.txt");
    let t = Instant::now();
    let mut child = samara()
        .args(args)
        .arg("--out")
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&err_path).unwrap())
        .spawn()
        .unwrap();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t.elapsed() > TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("samara {} ran longer than 20 s (a hang)", args.join(" "));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let stderr = std::fs::read_to_string(&err_path).unwrap_or_default();
    let code = status.code();
    assert!(
        matches!(code, Some(0..=2)),
        "samara {} exited with {status:?}: {stderr}",
        args.join(" ")
    );
    assert!(
        !stderr.contains("panicked") && !stderr.contains("memory allocation"),
        "samara {}: {stderr}",
        args.join(" ")
    );
    if code == Some(2) {
        assert!(
            !Path::new(&dir.path().join("new")).exists(),
            "samara {} failed but left its output folder",
            args.join(" ")
        );
    }
    counts.runs += 1;
    counts.by_code[code.unwrap() as usize] += 1;
    counts.max_ms = counts.max_ms.max(ms);
}

fn report(cmd: &str, flag: &str, c: &Counts) {
    eprintln!(
        "fuzz {cmd} {flag:<13} runs {:>5}  exit0 {:>5}  exit1 {:>5}  exit2 {:>5}  max {:>7.0} ms",
        c.runs, c.by_code[0], c.by_code[1], c.by_code[2], c.max_ms
    );
}

fn s(v: &[&str]) -> Vec<String> {
    v.iter().map(|x| x.to_string()).collect()
}

fn net() -> String {
    reference("base_model_denorm.onnx").display().to_string()
}

fn fuzz_simulate(per_flag: usize, seed: u64) -> usize {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // `--y0+net`: heights under the published network, clipped or not, with a random
    // integrator (an unclipped output can drive the state to NaN).
    let flags = ["--horizon", "--period", "--y0", "--controller", "--y0+net"];
    let mut total = 0;
    for flag in flags {
        let mut c = Counts::default();
        for _ in 0..per_flag {
            let mut args = s(&["simulate", "--no-plot", "--json"]);
            let value = match flag {
                "--horizon" => random_float(&mut rng, -6.0, 3.0),
                "--period" => random_float(&mut rng, -6.0, 3.0),
                "--y0" => match rng.gen_range(0..3) {
                    0 => format!(
                        "{}:{}:{}",
                        random_float(&mut rng, -6.0, 4.0),
                        random_float(&mut rng, -6.0, 4.0),
                        random_int(&mut rng, 3)
                    ),
                    1 => (0..rng.gen_range(1..5))
                        .map(|_| random_float(&mut rng, -6.0, 4.0))
                        .collect::<Vec<_>>()
                        .join(","),
                    _ => random_float(&mut rng, -6.0, 4.0),
                },
                "--y0+net" => {
                    args.extend(s(&["--controller", &net(), "--integrator"]));
                    args.push(["ode45", "tight", "dp5", "rk4"][rng.gen_range(0..4)].to_string());
                    if rng.gen_bool(0.5) {
                        args.push("--no-clip".into());
                    }
                    random_float(&mut rng, -3.0, 3.5)
                }
                _ => format!("constant:{}", random_float(&mut rng, -3.0, 0.0)),
            };
            if flag != "--horizon" {
                args.extend(s(&["--horizon", "0.5"]));
            }
            if !flag.starts_with("--y0") {
                args.extend(s(&["--y0", "2"]));
            }
            args.push(flag.trim_end_matches("+net").to_string());
            args.push(value);
            run_case(&args, &mut c);
        }
        report("simulate", flag, &c);
        total += c.runs;
    }
    total
}

fn fuzz_reach(per_flag: usize, seed: u64) -> usize {
    let net = net();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let flags = [
        "--horizon",
        "--period",
        "--y0",
        "--init",
        "--goal-ystar",
        "--goal-from",
        "--threads",
        "--max-leaves",
        "--samples",
    ];
    let names = ["v_xp", "v_yp", "omega", "theta", "x", "y", "E", "q", ""];
    let mut total = 0;
    for flag in flags {
        let mut c = Counts::default();
        for _ in 0..per_flag {
            let mut args = s(&["reach", "--network", &net]);
            let value = match flag {
                "--horizon" => random_float(&mut rng, -6.0, 0.5),
                "--period" => random_float(&mut rng, -6.0, 3.0),
                "--y0" => random_interval(&mut rng),
                "--init" => format!(
                    "{}={}",
                    names[rng.gen_range(0..names.len())],
                    random_interval(&mut rng)
                ),
                "--goal-ystar" | "--goal-from" => random_float(&mut rng, -6.0, 6.0),
                "--threads" => random_int(&mut rng, 3),
                "--max-leaves" => random_int(&mut rng, 5),
                _ => random_int(&mut rng, 3),
            };
            if flag != "--horizon" {
                args.extend(s(&["--horizon", "0.5"]));
            }
            if flag != "--y0" && flag != "--init" {
                args.extend(s(&["--y0", "2:2.01"]));
            }
            if flag == "--init" {
                args.extend(s(&["--y0", "2:2.01"]));
            }
            if flag != "--samples" {
                args.extend(s(&["--samples", "4"]));
            }
            if flag != "--max-leaves" {
                args.extend(s(&["--max-leaves", "2"]));
            }
            if flag == "--goal-from" {
                args.extend(s(&["--goal-ystar", "2"]));
            }
            if rng.gen_bool(0.3) {
                args.push("--no-clip".into());
            }
            args.push(flag.to_string());
            args.push(value);
            run_case(&args, &mut c);
        }
        report("reach", flag, &c);
        total += c.runs;
    }
    total
}

#[test]
fn simulate_numeric_flags_exit_0_1_or_2() {
    fuzz_simulate(20, 11);
}

#[test]
fn reach_numeric_flags_exit_0_1_or_2() {
    fuzz_reach(15, 12);
}

#[test]
#[ignore = "thousands of runs; run in release with --ignored --nocapture"]
fn numeric_flags_fuzz_long() {
    let per_flag: usize = std::env::var("SAMARA_FUZZ_PER_FLAG")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(250);
    let t = Instant::now();
    let n = fuzz_simulate(per_flag, 21) + fuzz_reach(per_flag, 22);
    eprintln!(
        "fuzz flags: {n} runs, {per_flag} per flag, {:.0} s",
        t.elapsed().as_secs_f64()
    );
}
