//! The NNet reader: a hand-written file evaluated by hand, clipping, malformed files
//! (errors with line numbers, never a panic) and a mutation fuzz loop.

#![allow(clippy::needless_range_loop)] // index loops mirror the maths

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_nn::nnet::{load, parse, NnetError};

/// 2 inputs, a hidden layer of 3 ReLUs, 1 output.
const SMALL: &str = "// A small test network
// written by hand
2,2,1,3,
2,3,1,
0,
-1.0,0.0,
1.0,2.0,
0.5,1.0,3.0,
2.0,4.0,10.0,
1.0,-2.0,
0.5,0.25,
-1.0,1.0,
0.1,
-0.2,
0.3,
1.0,-1.0,2.0,
0.5,
";

/// SMALL evaluated by hand from the numbers written in it.
fn small_by_hand(x0: f64, x1: f64) -> f64 {
    // Clip to [min, max].
    let c0 = x0.clamp(-1.0, 1.0);
    let c1 = x1.clamp(0.0, 2.0);
    // Normalise.
    let n0 = (c0 - 0.5) / 2.0;
    let n1 = (c1 - 1.0) / 4.0;
    // Hidden layer.
    let h0 = (1.0 * n0 - 2.0 * n1 + 0.1).max(0.0);
    let h1 = (0.5 * n0 + 0.25 * n1 - 0.2).max(0.0);
    let h2 = (-n0 + 1.0 * n1 + 0.3).max(0.0);
    // Output layer (linear) and denormalisation.
    let o = 1.0 * h0 - 1.0 * h1 + 2.0 * h2 + 0.5;
    o * 10.0 + 3.0
}

#[test]
fn small_network_matches_hand_evaluation_inside_and_outside_the_bounds() {
    let net = parse(SMALL, "small.nnet").unwrap();
    assert_eq!(net.n_inputs(), 2);
    assert_eq!(net.n_outputs(), 1);
    let pts = [
        (0.0, 1.0),
        (0.5, 0.5),
        (-1.0, 0.0),
        (1.0, 2.0),
        (0.9, 1.7),
        (-0.3, 1.2),
        // Outside [min, max]: clipped.
        (5.0, 1.0),
        (-7.0, 1.0),
        (0.2, -3.0),
        (0.2, 9.0),
        (100.0, -100.0),
        (-1e6, 1e6),
    ];
    for (x0, x1) in pts {
        let y = net.eval_f64(&[x0, x1])[0];
        let want = small_by_hand(x0, x1);
        // Far outside the bounds the f64 evaluation of the exact clipping
        // `lo + relu(x - lo) - relu(x - hi)` cancels: allow ulps of |x| (module doc).
        assert!(
            (y - want).abs() <= 1e-12 * (1.0 + want.abs()) + 1e-13 * (x0.abs() + x1.abs()),
            "at ({x0}, {x1}): {y} vs {want}"
        );
    }
    // Clipping: outside points equal their clipped versions.
    let e = |a: f64, b: f64| net.eval_f64(&[a, b])[0];
    // (Equal up to the rounding of the composed first layer, which sees 6 - 4 vs 2 - 0.)
    assert!((e(5.0, 1.0) - e(1.0, 1.0)).abs() < 1e-12);
    assert!((e(-7.0, 3.0) - e(-1.0, 2.0)).abs() < 1e-12);
    // A hand value: at (0, 1), n = (-0.25, 0): h = (0, 0, 0.55), o = 1.6, y = 19.
    assert!((e(0.0, 1.0) - 19.0).abs() < 1e-12);
    // Random points, in and out of the bounds.
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for _ in 0..1000 {
        let (a, b) = (rng.gen_range(-3.0..3.0), rng.gen_range(-2.0..4.0));
        let want = small_by_hand(a, b);
        assert!((e(a, b) - want).abs() <= 1e-12 * (1.0 + want.abs()));
    }
}

#[test]
fn infinite_input_bounds_mean_no_clipping() {
    let text = SMALL.replace("-1.0,0.0,\n1.0,2.0,", "-inf,0.0,\n1.0,inf,");
    let net = parse(&text, "inf.nnet").unwrap();
    for (x0, x1) in [(-5.0f64, 1.0f64), (0.3, 7.0), (3.0, -1.0)] {
        let c0 = x0.min(1.0);
        let c1 = x1.max(0.0);
        let want = {
            // Same arithmetic as small_by_hand without the clipping of the unbounded sides.
            let n0 = (c0 - 0.5) / 2.0;
            let n1 = (c1 - 1.0) / 4.0;
            let h0 = (n0 - 2.0 * n1 + 0.1).max(0.0);
            let h1 = (0.5 * n0 + 0.25 * n1 - 0.2).max(0.0);
            let h2 = (-n0 + n1 + 0.3).max(0.0);
            (h0 - h1 + 2.0 * h2 + 0.5) * 10.0 + 3.0
        };
        let y = net.eval_f64(&[x0, x1])[0];
        assert!(
            (y - want).abs() <= 1e-12 * (1.0 + want.abs()),
            "{y} vs {want}"
        );
    }
}

fn err_of(text: &str) -> String {
    match parse(text, "bad.nnet") {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn malformed_files_name_the_file_and_line() {
    let lines: Vec<&str> = SMALL.lines().collect();
    let without = |k: usize| -> String {
        let mut v = lines.clone();
        v.remove(k);
        v.join("\n")
    };
    let with = |k: usize, s: &str| -> String {
        let mut v = lines.clone();
        v[k] = s;
        v.join("\n")
    };
    let cases: Vec<(String, &str)> = vec![
        (String::new(), "bad.nnet:1: unexpected end of file"),
        (
            "// only a comment\n".into(),
            "bad.nnet:2: unexpected end of file",
        ),
        (with(2, "2,2,1,"), "bad.nnet:3: expected the header"),
        (with(2, "2,two,1,3,"), "bad.nnet:3:"),
        (with(3, "2,3,3,1,"), "bad.nnet:4: expected the layer sizes"),
        (
            with(3, "2,3,2,"),
            "bad.nnet:4: the layer sizes start with 2 and end with 2",
        ),
        (
            with(5, "-1.0,0.0,7.0,"),
            "bad.nnet:6: expected the input minimums",
        ),
        (
            with(6, "-2.0,2.0,"),
            "bad.nnet:7: input 0: maximum -2 is below minimum -1",
        ),
        (with(8, "2.0,0.0,10.0,"), "bad.nnet:9: range 2 is 0"),
        (
            with(9, "1.0,NaN,"),
            "bad.nnet:10: layer 1 weight row 1 of 3 (2 values): value 2 is `NaN`",
        ),
        (
            with(10, "0.5,abc,"),
            "bad.nnet:11: layer 1 weight row 2 of 3 (2 values): value 2 is `abc`",
        ),
        (
            with(12, "0.1,0.2,"),
            "bad.nnet:13: expected layer 1 bias 1 of 3",
        ),
        (with(15, "1.0,-1.0,inf,"), "bad.nnet:16:"),
        (
            without(16),
            "bad.nnet:17: unexpected end of file: expected layer 2 bias 1 of 1",
        ),
        (
            format!("{SMALL}0.7,\n"),
            "bad.nnet:18: unexpected data after the last layer",
        ),
        (
            with(3, "2,100000000,1,"),
            "bad.nnet:4: a layer size is 100000000",
        ),
        (with(2, "0,2,1,3,"), "bad.nnet:3: numLayers is 0"),
        (with(2, "99999999999999999999999,2,1,3,"), "bad.nnet:3:"),
        (with(5, "-1.0,1e999,"), "bad.nnet:6:"),
    ];
    for (text, want) in cases {
        let e = err_of(&text);
        assert!(
            e.starts_with(want),
            "got `{e}`, wanted a message starting with `{want}`"
        );
    }
    // The messages say what to do.
    let e = err_of(&without(16));
    assert!(e.contains("truncated"), "{e}");
}

#[test]
fn large_declared_sizes_are_refused_without_allocating() {
    let text = "4,100,100,60000,\n100,60000,60000,60000,100,\n";
    let e = err_of(text);
    assert!(e.contains("parameters, more than"), "{e}");
}

#[test]
fn load_names_the_file() {
    let e = load(std::path::Path::new("/nonexistent/dir/x.nnet")).unwrap_err();
    assert!(matches!(e, NnetError::Io { .. }));
    assert!(
        e.to_string()
            .starts_with("/nonexistent/dir/x.nnet: cannot read"),
        "{e}"
    );
    let dir = std::env::temp_dir().join(format!("samara-nnet-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("small.nnet");
    std::fs::write(&p, SMALL).unwrap();
    let net = load(&p).unwrap();
    assert!((net.eval_f64(&[0.0, 1.0])[0] - 19.0).abs() < 1e-12);
    std::fs::write(&p, [0xffu8, 0xfe, 0x00]).unwrap();
    let e = load(&p).unwrap_err().to_string();
    assert!(
        e.contains("small.nnet:1: the text is not valid UTF-8"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn random_mutations_never_panic() {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let pieces = [
        "",
        ",",
        "nan",
        "inf",
        "-",
        "1e308",
        "1e309",
        "0",
        "999999999",
        "x",
        "\n",
        "//",
        ",,",
        "-0",
        "1.5",
        " ",
    ];
    let mut ok = 0;
    for _ in 0..3000 {
        let mut t: Vec<String> = SMALL.lines().map(String::from).collect();
        for _ in 0..rng.gen_range(1..4) {
            if t.is_empty() {
                t.push(String::new());
            }
            let k = rng.gen_range(0..t.len());
            match rng.gen_range(0..6) {
                0 => {
                    t.remove(k);
                    if t.is_empty() {
                        t.push(String::new());
                    }
                }
                1 => {
                    let l = t[k].clone();
                    t.insert(k, l);
                }
                2 => {
                    // Replace one field.
                    let mut f: Vec<String> = t[k].split(',').map(String::from).collect();
                    let j = rng.gen_range(0..f.len());
                    f[j] = pieces[rng.gen_range(0..pieces.len())].to_string();
                    t[k] = f.join(",");
                }
                3 => {
                    // Byte-level character flip (ASCII to keep valid UTF-8).
                    let mut b = t[k].clone().into_bytes();
                    if !b.is_empty() {
                        let j = rng.gen_range(0..b.len());
                        b[j] = rng.gen_range(32u8..127);
                    }
                    t[k] = String::from_utf8(b).unwrap();
                }
                4 => t.truncate(k),
                _ => t[k] = pieces[rng.gen_range(0..pieces.len())].to_string(),
            }
        }
        let text = t.join("\n");
        match parse(&text, "fuzz.nnet") {
            Ok(net) => {
                ok += 1;
                net.validate().unwrap();
                let y = net.eval_f64(&vec![0.5; net.n_inputs()]);
                assert_eq!(y.len(), net.n_outputs());
            }
            Err(e) => {
                let m = e.to_string();
                assert!(m.starts_with("fuzz.nnet:"), "{m}");
            }
        }
    }
    eprintln!("{ok} of 3000 mutations still parse");
}

/// An ACAS Xu network (7 layers of 50) from the reference implementation
/// (github.com/sisl/NNet, `nnet/TestNetwork.nnet`, 167 KB, not in this repository),
/// against the expected output of its own test suite (`test/test_nnet.py`: input
/// `[1, 1, 1, 100, 1]`, rtol 1e-5). Set `SAMARA_NNET_DIR` to a directory holding the file.
#[test]
#[ignore = "needs the external file TestNetwork.nnet (github.com/sisl/NNet nnet/); set SAMARA_NNET_DIR"]
fn matches_the_reference_implementation() {
    let dir = std::env::var("SAMARA_NNET_DIR")
        .expect("set SAMARA_NNET_DIR to a directory holding TestNetwork.nnet");
    let net = load(&std::path::Path::new(&dir).join("TestNetwork.nnet"))
        .unwrap_or_else(|e| panic!("{e}"));
    let y = net.eval_f64(&[1.0, 1.0, 1.0, 100.0, 1.0]);
    let want = [
        270.94961805,
        280.8974763,
        274.55254776,
        288.10071007,
        256.18037737,
    ];
    for j in 0..5 {
        assert!(
            (y[j] - want[j]).abs() <= 1e-5 * want[j].abs(),
            "{y:?} vs {want:?}"
        );
    }
}
