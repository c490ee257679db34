//! Every network of the VNN-COMP 2021 benchmarks (issue 37), and of the 2023/2024
//! folders given, loads and evaluates: over files fetched outside the repository (too
//! large to check in), so `#[ignore]`d.
//!
//! `SAMARA_VNNCOMP2021=.../vnncomp2021/benchmarks cargo test -p samara-nn --release
//!  --test all vnncomp_networks:: -- --ignored --nocapture` (and `SAMARA_VNNCOMP_DIRS`, below)
//!
//! Per network: the graph import, 100 random inputs in [0, 1] through the graph
//! evaluation and, where the network lowers to the verifier's chain, through the chain
//! (equal to 1e-9 relative). With `SAMARA_PYTHON` set to a Python that has onnxruntime,
//! bench/vnncomp/check_onnx.py then compares both with onnxruntime on 100 inputs
//! (1e-5 relative) and must exit 0.

use rand::{Rng, SeedableRng};
use samara_nn::onnx;
use std::path::{Path, PathBuf};

const BENCHMARKS: &[&str] = &[
    "verivital",
    "oval21",
    "marabou-cifar10",
    "cifar10_resnet",
    "nn4sys",
    "cifar2020",
    "collins_rul_cnn",
    "rl_benchmarks",
];

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
#[ignore = "needs the VNN-COMP benchmark files (SAMARA_VNNCOMP2021), fetched outside the repository"]
fn vnncomp_networks_load_and_evaluate() {
    let root = PathBuf::from(std::env::var("SAMARA_VNNCOMP2021").expect("set SAMARA_VNNCOMP2021"));
    let dirs: Vec<PathBuf> = BENCHMARKS.iter().map(|b| root.join(b)).collect();
    check_dirs(&dirs, 2021);
}

/// The VNN-COMP 2023/2024 benchmark folders this machine holds (issues 36 and 37):
/// `SAMARA_VNNCOMP_DIRS=/tmp/vnn23/cgan:/tmp/vnn23/dist_shift:...` (folders
/// separated by `:`), e.g. tllverifybench, dist_shift, acasxu, collins_rul_cnn,
/// traffic_signs_recognition, cgan, metaroom, cora, safenlp, linearizenn.
#[test]
#[ignore = "needs the VNN-COMP 2023/2024 benchmark files (SAMARA_VNNCOMP_DIRS), fetched outside the repository"]
fn vnncomp_2023_2024_networks_load_and_evaluate() {
    let dirs: Vec<PathBuf> = std::env::var("SAMARA_VNNCOMP_DIRS")
        .expect("set SAMARA_VNNCOMP_DIRS")
        .split(':')
        .map(PathBuf::from)
        .collect();
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
    if let Ok(py) = std::env::var("SAMARA_PYTHON") {
        let script =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../bench/vnncomp/check_onnx.py");
        let st = std::process::Command::new(py)
            .arg(script)
            .args(&dirs)
            .status()
            .unwrap();
        assert!(
            st.success(),
            "check_onnx.py found a disagreement with onnxruntime"
        );
    }
}
