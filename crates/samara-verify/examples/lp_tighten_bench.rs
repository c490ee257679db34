//! What LP tightening does at the root, per network: unstable neurons before and after,
//! the mean width of their bounds, the LPs solved and the time, serial and parallel:
//! `cargo run --release -p samara-verify --example lp_tighten_bench -- REFERENCE_DIR [NET.onnx ...]`
//! (the published networks over the case study's input domain, then any raw-unit
//! networks given, e.g. a 6-64-32-1 one trained by samara).

use samara_verify::net::PwlNet;
use samara_verify::tighten::{base_bounds, lp_tighten};
use std::time::Instant;

fn unstable(p: &PwlNet, lo: &[Vec<f64>], hi: &[Vec<f64>]) -> (usize, f64) {
    let (mut n, mut w) = (0, 0.0);
    for k in 0..p.maps.len() {
        if !p.maps[k].1 {
            continue;
        }
        for i in 0..lo[k].len() {
            if lo[k][i] < 0.0 && hi[k][i] > 0.0 {
                n += 1;
            }
            w += hi[k][i] - lo[k][i];
        }
    }
    let total: usize = p.maps.iter().filter(|m| m.1).map(|m| m.0.out).sum();
    (n, w / total.max(1) as f64)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = std::path::PathBuf::from(
        args.first()
            .cloned()
            .unwrap_or("../shared/reference".into()),
    );
    let text = std::fs::read_to_string(dir.join("Normalisation_Constants.csv")).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .map(|l| l.split(',').map(|v| v.trim().parse().unwrap()).collect())
        .collect();
    let (c, s) = (rows[0][..6].to_vec(), rows[1][..6].to_vec());
    let raw_lo = c.clone();
    let raw_hi: Vec<f64> = c.iter().zip(&s).map(|(a, b)| a + b).collect();
    let mut files: Vec<std::path::PathBuf> = [
        "base_model_norm.onnx",
        "adversarial_model_norm.onnx",
        "base_model_denorm.onnx",
        "adversarial_model_denorm.onnx",
    ]
    .iter()
    .map(|f| dir.join(f))
    .collect();
    files.extend(args.iter().skip(1).map(std::path::PathBuf::from));
    println!(
        "{:40} {:>9} {:>9} {:>10} {:>10} {:>5} {:>10} {:>10}",
        "network", "unstable", "after", "mean width", "after", "LPs", "serial s", "parallel s"
    );
    for f in files {
        let net = samara_nn::onnx::load(&f).unwrap();
        let p = PwlNet::from_network(&net).unwrap();
        // Normalised networks take z = (x - C) / S in [0, 1]; PwlNet is in raw units
        // (the normalisation is part of the network when stored, else the box is [0, 1]).
        let (xl, xh) = if net.input_norm.is_none() && f.to_string_lossy().contains("_norm") {
            (vec![0.0; 6], vec![1.0; 6])
        } else {
            (raw_lo.clone(), raw_hi.clone())
        };
        let fixed: Vec<Vec<i8>> = p
            .maps
            .iter()
            .filter(|m| m.1)
            .map(|m| vec![0; m.0.out])
            .collect();
        let (lo0, hi0) = base_bounds(&p, &xl, &xh, &fixed).unwrap();
        let (u0, w0) = unstable(&p, &lo0, &hi0);
        let mut secs = [0.0; 2];
        let mut out = (lo0.clone(), hi0.clone());
        let mut lps = 0;
        for (j, par) in [false, true].into_iter().enumerate() {
            // Best of 5.
            secs[j] = f64::INFINITY;
            for _ in 0..5 {
                let (mut lo, mut hi) = (lo0.clone(), hi0.clone());
                let t = Instant::now();
                let st = lp_tighten(&p, &xl, &xh, &[], &fixed, &mut lo, &mut hi, par).unwrap();
                secs[j] = secs[j].min(t.elapsed().as_secs_f64());
                lps = st.lps;
                out = (lo, hi);
            }
        }
        let (u1, w1) = unstable(&p, &out.0, &out.1);
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        println!(
            "{name:40} {u0:>9} {u1:>9} {w0:>10.4} {w1:>10.4} {lps:>5} {:>10.4} {:>10.4}",
            secs[0], secs[1]
        );
    }
}
