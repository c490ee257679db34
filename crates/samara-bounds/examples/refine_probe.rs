//! Development probe (i52-m): per ReLU layer, how many neurons CROWN / alpha-CROWN
//! leave unstable on one mnistfc instance, and how many of those a projected-gradient
//! search shows to take both signs on the box (the rest are what an exact per-neuron
//! refinement could still fix). `cargo run --release -p samara-bounds --example
//! refine_probe -- NET.onnx PROP.vnnlib [n15|a15|n60|a60] [LAYERS]`; with
//! `REFINE=LAST,NODES[,SECOND]` also runs [`samara_bounds::refine::stabilise`] on maps
//! `1..=LAST` (then `LAST+1..=SECOND`), each followed by alpha-CROWN again.

use samara_bounds::pwl::PwlNet;
use samara_bounds::symbolic::{self, Ascent};
use samara_nn::Affine;
use std::time::Instant;

fn read_box(text: &str, n: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut lo, mut hi) = (vec![0.0; n], vec![0.0; n]);
    for line in text.lines() {
        let t: Vec<&str> = line
            .split(|c: char| c == '(' || c == ')' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .collect();
        if t.len() == 4 && t[0] == "assert" && t[2].starts_with("X_") {
            let i: usize = t[2][2..].parse().unwrap();
            let v: f64 = t[3].parse().unwrap();
            if t[1] == "<=" {
                hi[i] = v;
            } else {
                lo[i] = v;
            }
        }
    }
    (lo, hi)
}

/// z of map k neuron i at x, and its gradient in x.
fn value_grad(maps: &[(Affine, bool)], k: usize, i: usize, x: &[f64]) -> (f64, Vec<f64>) {
    let mut acts = vec![x.to_vec()];
    let mut zs = Vec::new();
    for (j, (m, r)) in maps.iter().enumerate().take(k + 1) {
        let mut z = vec![0.0; m.out];
        m.apply_f64(acts.last().unwrap(), &mut z);
        zs.push(z.clone());
        if *r && j < k {
            z.iter_mut().for_each(|v| *v = v.max(0.0));
        }
        acts.push(z);
    }
    let val = zs[k][i];
    let mut g = vec![0.0; maps[k].0.out];
    g[i] = 1.0;
    for j in (0..=k).rev() {
        let m = &maps[j].0;
        if j < k && maps[j].1 {
            for (gv, z) in g.iter_mut().zip(&zs[j]) {
                if *z <= 0.0 {
                    *gv = 0.0;
                }
            }
        }
        let mut gi = vec![0.0; m.inp];
        for (o, &go) in g.iter().enumerate() {
            if go != 0.0 {
                for (p, v) in gi.iter_mut().enumerate() {
                    *v += go * m.weight(o, p);
                }
            }
        }
        g = gi;
    }
    (val, g)
}

fn pgd(maps: &[(Affine, bool)], k: usize, i: usize, sign: f64, lo: &[f64], hi: &[f64]) -> f64 {
    let mut best = f64::INFINITY;
    let mut x: Vec<f64> = lo.iter().zip(hi).map(|(a, b)| 0.5 * (a + b)).collect();
    for it in 0..25 {
        let (v, g) = value_grad(maps, k, i, &x);
        best = best.min(sign * v);
        let step = 0.5 / (1.0 + it as f64 * 0.2);
        for t in 0..x.len() {
            let w = hi[t] - lo[t];
            x[t] = (x[t] - sign * step * w * g[t].signum()).clamp(lo[t], hi[t]);
        }
    }
    best
}

fn count(pre: &[Vec<(f64, f64)>]) -> Vec<usize> {
    pre.iter()
        .map(|l| l.iter().filter(|b| b.0 < 0.0 && b.1 > 0.0).count())
        .collect()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let net = samara_nn::load(&args[1]).unwrap();
    let pwl = PwlNet::from_network(&net).unwrap();
    let maps = &pwl.maps;
    let text = std::fs::read_to_string(&args[2]).unwrap();
    let (lo, hi) = read_box(&text, pwl.n_inputs());
    let fwd = symbolic::hidden_pre(maps, &lo, &hi, None);
    let mut crown = symbolic::crown_pre(maps, &lo, &hi, Some(&fwd));
    crown.truncate(maps.len() - 1);
    println!(
        "maps {:?}",
        maps.iter()
            .map(|m| (m.0.inp, m.0.out, m.1))
            .collect::<Vec<_>>()
    );
    println!("crown {:?}", count(&crown));
    let which = args.get(3).map(|s| s.as_str()).unwrap_or("n15");
    let t = Instant::now();
    let mut pre = crown.clone();
    let (iters, asc) = match which {
        "a15" => (15, Ascent::Adam(0.3)),
        "a60" => (60, Ascent::Adam(0.3)),
        "n60" => (60, Ascent::Normalised),
        _ => (15, Ascent::Normalised),
    };
    symbolic::alpha_pre_with(maps, &mut pre, &lo, &hi, iters, asc, false, None);
    println!(
        "{which} {:?} in {:.1} s",
        count(&pre),
        t.elapsed().as_secs_f64()
    );
    for (k, l) in pre.iter().enumerate() {
        println!("L{k} crown {:?} alpha {:?}", &crown[k][..3], &l[..3]);
    }
    if let Ok(lim) = std::env::var("REFINE") {
        let mut it = lim.split(',');
        let last: usize = it.next().unwrap().parse().unwrap();
        let nl: u64 = it.next().unwrap().parse().unwrap();
        let second: usize = it.next().map(|s| s.parse().unwrap()).unwrap_or(0);
        let t = Instant::now();
        let r = samara_bounds::refine::stabilise(maps, &mut pre, &lo, &hi, 1..=last, nl, None);
        println!(
            "refine {:?} in {:.1} s: {:?}",
            r,
            t.elapsed().as_secs_f64(),
            count(&pre)
        );
        let t = Instant::now();
        symbolic::alpha_pre_with(maps, &mut pre, &lo, &hi, iters, asc, false, None);
        println!(
            "alpha again {:?} in {:.1} s",
            count(&pre),
            t.elapsed().as_secs_f64()
        );
        if second > last {
            let t = Instant::now();
            let r = samara_bounds::refine::stabilise(
                maps,
                &mut pre,
                &lo,
                &hi,
                last + 1..=second,
                nl,
                None,
            );
            println!(
                "refine {:?} in {:.1} s: {:?}",
                r,
                t.elapsed().as_secs_f64(),
                count(&pre)
            );
            let t = Instant::now();
            symbolic::alpha_pre_with(maps, &mut pre, &lo, &hi, iters, asc, false, None);
            println!(
                "alpha again {:?} in {:.1} s",
                count(&pre),
                t.elapsed().as_secs_f64()
            );
        }
    }
    let layers: usize = args.get(4).map(|s| s.parse().unwrap()).unwrap_or(3);
    for (k, layer) in pre.iter().enumerate().take(layers) {
        let un: Vec<usize> = (0..layer.len())
            .filter(|&i| layer[i].0 < 0.0 && layer[i].1 > 0.0)
            .collect();
        let mut both = 0;
        let mut gl = Vec::new();
        for &i in &un {
            let mn = pgd(maps, k, i, 1.0, &lo, &hi);
            let mx = -pgd(maps, k, i, -1.0, &lo, &hi);
            if mn < 0.0 && mx > 0.0 {
                both += 1;
            } else {
                let (l, u) = layer[i];
                gl.push(if mn >= 0.0 {
                    format!("+{:.2}/{:.2}", l, mn)
                } else {
                    format!("-{:.2}/{:.2}", u, mx)
                });
            }
        }
        println!(
            "layer {k}: {} unstable, {both} take both signs; others (bound/attack): {:?}",
            un.len(),
            &gl[..gl.len().min(12)]
        );
    }
}
