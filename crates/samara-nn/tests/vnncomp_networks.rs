//! Every network of the VNN-COMP 2021 benchmarks and of 2022's collins_rul_cnn and
//! rl_benchmarks (issue 37), and of the 2023/2024 folders given, loads and evaluates
//! equal to onnxruntime: over files fetched outside the repository (too large to check
//! in), so `#[ignore]`d, and skipped with a message when the folders are not given.
//!
//! `SAMARA_VNNCOMP2021=ROOT[:ROOT...] SAMARA_VNNCOMP2022=ROOT[:ROOT...]
//!  SAMARA_PYTHON=.../python cargo test -p samara-nn --release --test all vnncomp_networks::
//!  -- --ignored --nocapture` (each ROOT a `benchmarks` folder of the competition's
//! repository; every benchmark is looked up under every root, so networks split over
//! several fetches are found), and `SAMARA_VNNCOMP_DIRS` (below).
//!
//! Per network: the graph import, 100 random inputs in [0, 1] through the graph
//! evaluation and, where the network lowers to the verifier's chain, through the chain
//! (equal to 1e-9 relative: the lowering against the graph, both samara's). The golden
//! values are onnxruntime's: with `SAMARA_PYTHON` set to a Python that has onnxruntime,
//! bench/vnncomp/check_onnx.py compares both evaluations with onnxruntime on 100
//! inputs per network drawn from the boxes of the benchmark's own properties
//! (`--spec-box`: [0, 1] misses nn4sys's keys, where every output is 0), 1e-5 relative,
//! and must exit 0. Without `SAMARA_PYTHON` the test says that it checked samara
//! against itself only. Calling onnxruntime at test time rather than storing its
//! outputs: the networks are not in the repository either, and the outputs of 100
//! inputs of 3072 entries per network would be megabytes of golden files.

use rand::{Rng, SeedableRng};
use samara_nn::onnx;
use std::path::{Path, PathBuf};

/// The benchmarks of 2021 (issue 37's list, with ACAS Xu and the fully connected ones).
const BENCHMARKS_2021: &[&str] = &[
    "acasxu",
    "verivital",
    "oval21",
    "marabou-cifar10",
    "cifar10_resnet",
    "nn4sys",
    "cifar2020",
    "eran",
    "mnistfc",
];

/// The benchmarks of 2022 the issue names.
const BENCHMARKS_2022: &[&str] = &["collins_rul_cnn", "rl_benchmarks"];

/// The folders `ROOT/NAME` that exist, for each root of the `:`-separated `var` and each
/// name; `None` (and a message) when `var` is unset.
fn benchmark_dirs(var: &str, names: &[&str]) -> Option<Vec<PathBuf>> {
    let Ok(roots) = std::env::var(var) else {
        println!("{var} is not set: skipped (see the module documentation)");
        return None;
    };
    let mut dirs = Vec::new();
    for name in names {
        let found: Vec<PathBuf> = roots
            .split(':')
            .map(|r| Path::new(r).join(name))
            .filter(|d| d.is_dir())
            .collect();
        if found.is_empty() {
            println!("{name}: not under {roots}");
        }
        dirs.extend(found);
    }
    Some(dirs)
}

fn onnx_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return;
    };
    let mut es: Vec<_> = rd.flatten().map(|e| e.path()).collect();
    es.sort();
    for p in es {
        if p.is_dir() {
            onnx_files(&p, out);
        } else if p.to_string_lossy().ends_with(".onnx")
            || p.to_string_lossy().ends_with(".onnx.gz")
        {
            out.push(p);
        }
    }
}

/// A plain ONNX file (gzipped ones unpacked with `gzip -dc` into the temp folder).
fn plain(p: &Path) -> PathBuf {
    if !p.to_string_lossy().ends_with(".gz") {
        return p.to_path_buf();
    }
    let out = std::env::temp_dir().join(p.file_stem().unwrap());
    let bytes = std::process::Command::new("gzip")
        .arg("-dc")
        .arg(p)
        .output()
        .unwrap()
        .stdout;
    std::fs::write(&out, bytes).unwrap();
    out
}

#[test]
#[ignore = "needs the VNN-COMP benchmark files (SAMARA_VNNCOMP2021, SAMARA_VNNCOMP2022), fetched outside the repository"]
fn vnncomp_networks_load_and_evaluate() {
    let mut dirs = Vec::new();
    let mut given = false;
    for (var, names) in [
        ("SAMARA_VNNCOMP2021", BENCHMARKS_2021),
        ("SAMARA_VNNCOMP2022", BENCHMARKS_2022),
    ] {
        if let Some(d) = benchmark_dirs(var, names) {
            given = true;
            dirs.extend(d);
        }
    }
    if given {
        check_dirs(&dirs, 2021);
    }
}

/// The VNN-COMP 2023/2024 benchmark folders this machine holds (issues 36 and 37):
/// `SAMARA_VNNCOMP_DIRS=/tmp/vnn23/cgan:/tmp/vnn23/dist_shift:...` (folders
/// separated by `:`), e.g. tllverifybench, dist_shift, acasxu, collins_rul_cnn,
/// traffic_signs_recognition, cgan, metaroom, cora, safenlp, linearizenn.
#[test]
#[ignore = "needs the VNN-COMP 2023/2024 benchmark files (SAMARA_VNNCOMP_DIRS), fetched outside the repository"]
fn vnncomp_2023_2024_networks_load_and_evaluate() {
    let Ok(dirs) = std::env::var("SAMARA_VNNCOMP_DIRS") else {
        println!("SAMARA_VNNCOMP_DIRS is not set: skipped (see the module documentation)");
        return;
    };
    let dirs: Vec<PathBuf> = dirs.split(':').map(PathBuf::from).collect();
    check_dirs(&dirs, 2023);
}

/// Every network under `dirs`: graph import, 100 random inputs through the graph and
/// the lowered chain, then check_onnx.py against onnxruntime (see the module docs).
fn check_dirs(benchmarks: &[PathBuf], seed: u64) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut dirs = Vec::new();
    let mut n = 0;
    for dir in benchmarks {
        let mut files = Vec::new();
        onnx_files(dir, &mut files);
        if files.is_empty() {
            println!("no networks under {}", dir.display());
            continue;
        }
        dirs.push(dir.clone());
        for f in files {
            let p = plain(&f);
            let g = onnx::load_graph(&p).unwrap_or_else(|e| panic!("{e}"));
            let chain = match onnx::load(&p) {
                Ok(c) => Some(c),
                Err(e) => {
                    println!("{}: evaluated, not lowered: {e}", f.display());
                    None
                }
            };
            for _ in 0..100 {
                let x: Vec<f64> = (0..g.n_inputs()).map(|_| rng.gen_range(0.0..1.0)).collect();
                let y = g.eval_f64(&x).unwrap();
                assert!(y.iter().all(|v| v.is_finite()), "{}", f.display());
                if let Some(c) = &chain {
                    let yc = c.eval_f64(&x);
                    for (a, b) in y.iter().zip(&yc) {
                        assert!(
                            (a - b).abs() <= 1e-9 * a.abs().max(1.0),
                            "{}: {a} vs {b}",
                            f.display()
                        );
                    }
                }
            }
            println!(
                "{}: {} inputs, {} outputs, lowered: {}",
                f.display(),
                g.n_inputs(),
                g.n_outputs(),
                chain.is_some()
            );
            n += 1;
        }
    }
    assert!(n > 0, "no networks found under {benchmarks:?}");
    let Ok(py) = std::env::var("SAMARA_PYTHON") else {
        println!(
            "SAMARA_PYTHON is not set: {n} networks checked against samara's own graph \
             evaluation only, not against onnxruntime"
        );
        return;
    };
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../bench/vnncomp/check_onnx.py");
    let st = std::process::Command::new(py)
        .arg(script)
        .args(["--n", "100", "--spec-box"])
        .args(&dirs)
        .status()
        .unwrap();
    assert!(
        st.success(),
        "check_onnx.py found a disagreement with onnxruntime (or a network it could not import)"
    );
}
