//! Standing fuzz suite of the readers (issue 17): the ONNX loader, the CSV reader and the
//! IDX reader get mutations of the published files (byte flips, truncations,
//! insertions, huge declared sizes, NaN weights) and random bytes, and must answer Ok or
//! Err: never panic, never hang, never allocate without bound.
//!
//! - A panic is caught per case and counted (the suite fails on the first kind with one).
//! - A hang: a watchdog aborts the process when one case runs longer than 20 s.
//! - A huge allocation: this test binary's allocator refuses any single allocation over
//!   512 MB, which aborts the process with "memory allocation of N bytes failed".
//!
//! CI runs a few hundred cases per input kind; `cargo test --release -p samara-nn --test
//! fuzz -- --ignored --nocapture` runs 10,000 per kind and prints the counts.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_nn::data::{parse_csv, parse_idx, MinMax};
use samara_nn::onnx::proto::ModelProto;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// Largest single allocation allowed in this test binary.
const ALLOC_CAP: usize = 512 << 20;

struct Capped;

// SAFETY: forwards to the system allocator; refusing (null) is allowed by the contract.
unsafe impl GlobalAlloc for Capped {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        if l.size() > ALLOC_CAP {
            return std::ptr::null_mut();
        }
        System.alloc(l)
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        System.dealloc(p, l)
    }
    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        if l.size() > ALLOC_CAP {
            return std::ptr::null_mut();
        }
        System.alloc_zeroed(l)
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        if n > ALLOC_CAP {
            return std::ptr::null_mut();
        }
        System.realloc(p, l, n)
    }
}

#[global_allocator]
static GLOBAL: Capped = Capped;

/// Milliseconds since the epoch of the running case's start (0: none running).
static CASE_START: AtomicU64 = AtomicU64::new(0);

fn now_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() as u64)
        .unwrap_or(0)
}

fn start_watchdog() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        std::thread::spawn(|| loop {
            std::thread::sleep(Duration::from_millis(500));
            let s = CASE_START.load(Ordering::Relaxed);
            if s != 0 && now_ms().saturating_sub(s) > 20_000 {
                eprintln!("fuzz: one case ran longer than 20 s (a hang); aborting");
                std::process::abort();
            }
        });
    });
}

use samara_testkit as support;
use support::reference;

/// Counts of one input kind.
#[derive(Default, Debug)]
struct Stats {
    ok: usize,
    err: usize,
    panics: usize,
    max_ms: f64,
    first_panic: Option<String>,
}

/// Run `f` on one case, catching panics and timing it.
fn case<F: FnOnce() -> bool + std::panic::UnwindSafe>(st: &mut Stats, what: &str, f: F) {
    CASE_START.store(now_ms().max(1), Ordering::Relaxed);
    let t = Instant::now();
    let r = std::panic::catch_unwind(f);
    st.max_ms = st.max_ms.max(t.elapsed().as_secs_f64() * 1e3);
    CASE_START.store(0, Ordering::Relaxed);
    match r {
        Ok(true) => st.ok += 1,
        Ok(false) => st.err += 1,
        Err(_) => {
            st.panics += 1;
            st.first_panic.get_or_insert_with(|| what.to_string());
        }
    }
}

fn report(kind: &str, st: &Stats) {
    eprintln!(
        "fuzz {kind:<28} cases {:>6}  ok {:>6}  err {:>6}  panics {}  max {:.1} ms",
        st.ok + st.err + st.panics,
        st.ok,
        st.err,
        st.panics,
        st.max_ms
    );
    assert_eq!(st.panics, 0, "{kind}: panic on {:?}", st.first_panic);
}

// ---------------------------------------------------------------- byte mutations

fn flip(rng: &mut ChaCha8Rng, b: &[u8]) -> Vec<u8> {
    let mut v = b.to_vec();
    if v.is_empty() {
        return v;
    }
    for _ in 0..rng.gen_range(1..=8) {
        let i = rng.gen_range(0..v.len());
        v[i] ^= rng.gen_range(1..=255u8);
    }
    v
}

fn truncate(rng: &mut ChaCha8Rng, b: &[u8]) -> Vec<u8> {
    b[..rng.gen_range(0..b.len().max(1))].to_vec()
}

fn insert(rng: &mut ChaCha8Rng, b: &[u8]) -> Vec<u8> {
    let mut v = b.to_vec();
    let at = rng.gen_range(0..=v.len());
    let n = rng.gen_range(1..=16);
    let ins: Vec<u8> = (0..n).map(|_| rng.gen()).collect();
    v.splice(at..at, ins);
    v
}

fn random_bytes(rng: &mut ChaCha8Rng) -> Vec<u8> {
    let n = rng.gen_range(0..4096);
    (0..n).map(|_| rng.gen()).collect()
}

const HUGE: [i64; 8] = [
    1 << 40,
    1 << 31,
    (1 << 32) - 1,
    i64::MAX,
    -1,
    0,
    1 << 20,
    1 << 62,
];

// ---------------------------------------------------------------- ONNX

const ONNX_FILES: [&str; 5] = [
    "base_model_norm.onnx",
    "base_model_denorm.onnx",
    "adversarial_model_norm.onnx",
    "adversarial_model_denorm.onnx",
    "merged_model_base.onnx",
];

fn load_case(st: &mut Stats, what: &str, bytes: Vec<u8>) {
    case(st, what, move || {
        match samara_nn::onnx::from_bytes(&bytes, "fuzz.onnx") {
            Ok(net) => {
                let y = net.eval_f64(&vec![0.5; net.n_inputs()]);
                assert_eq!(y.len(), net.n_outputs());
                true
            }
            Err(e) => {
                assert!(e.to_string().starts_with("fuzz.onnx"), "{e}");
                false
            }
        }
    });
}

/// A declared size from [`HUGE`] (or a random one) in a tensor shape or the input shape.
fn huge_dims(rng: &mut ChaCha8Rng, m: &ModelProto) -> ModelProto {
    let mut m = m.clone();
    let v = if rng.gen_bool(0.75) {
        HUGE[rng.gen_range(0..HUGE.len())]
    } else {
        rng.gen()
    };
    let g = m.graph.as_mut().expect("graph");
    if rng.gen_bool(0.5) && !g.initializer.is_empty() {
        let i = rng.gen_range(0..g.initializer.len());
        let t = &mut g.initializer[i];
        if t.dims.is_empty() || rng.gen_bool(0.2) {
            t.dims.push(v);
        } else {
            let k = rng.gen_range(0..t.dims.len());
            t.dims[k] = v;
        }
    } else if let Some(d) = g
        .input
        .iter_mut()
        .filter_map(|i| i.r#type.as_mut()?.tensor_type.as_mut()?.shape.as_mut())
        .flat_map(|s| s.dim.iter_mut())
        .last()
    {
        d.dim_value = Some(v);
    }
    m
}

/// One weight (float_data or raw_data) set to NaN or an infinity.
fn nan_weight(rng: &mut ChaCha8Rng, m: &ModelProto) -> ModelProto {
    let mut m = m.clone();
    let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][rng.gen_range(0..3)];
    let g = m.graph.as_mut().expect("graph");
    let floats: Vec<usize> = (0..g.initializer.len())
        .filter(|&i| g.initializer[i].data_type == 1)
        .collect();
    if floats.is_empty() {
        return m;
    }
    let t = &mut g.initializer[floats[rng.gen_range(0..floats.len())]];
    if !t.raw_data.is_empty() {
        let k = rng.gen_range(0..t.raw_data.len() / 4);
        t.raw_data[4 * k..4 * k + 4].copy_from_slice(&bad.to_le_bytes());
    } else if !t.float_data.is_empty() {
        let k = rng.gen_range(0..t.float_data.len());
        t.float_data[k] = bad;
    }
    m
}

fn fuzz_onnx(per_kind: usize, seed: u64) {
    use prost::Message;
    start_watchdog();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let files: Vec<(String, Vec<u8>)> = ONNX_FILES
        .iter()
        .map(|f| (f.to_string(), std::fs::read(reference(f)).unwrap()))
        .collect();
    let models: Vec<ModelProto> = files
        .iter()
        .map(|(_, b)| ModelProto::decode(b.as_slice()).unwrap())
        .collect();
    // The originals load.
    for (f, b) in &files {
        samara_nn::onnx::from_bytes(b, f).unwrap();
    }
    type Mut = fn(&mut ChaCha8Rng, &[u8]) -> Vec<u8>;
    let byte_kinds: [(&str, Mut); 3] = [
        ("onnx byte flips", flip),
        ("onnx truncations", truncate),
        ("onnx insertions", insert),
    ];
    for (kind, m) in byte_kinds {
        let mut st = Stats::default();
        for i in 0..per_kind {
            let (f, b) = &files[i % files.len()];
            load_case(&mut st, &format!("{kind} of {f}, case {i}"), m(&mut rng, b));
        }
        report(kind, &st);
    }
    let mut st = Stats::default();
    for i in 0..per_kind {
        let k = i % models.len();
        let bytes = huge_dims(&mut rng, &models[k]).encode_to_vec();
        load_case(
            &mut st,
            &format!("huge dims of {}, case {i}", files[k].0),
            bytes,
        );
    }
    report("onnx huge dims", &st);
    let mut st = Stats::default();
    for i in 0..per_kind {
        let k = i % models.len();
        let bytes = nan_weight(&mut rng, &models[k]).encode_to_vec();
        // A NaN or infinite weight is always an error.
        case(&mut st, &format!("nan weight, case {i}"), move || {
            assert!(samara_nn::onnx::from_bytes(&bytes, "fuzz.onnx").is_err());
            false
        });
    }
    report("onnx NaN/inf weights", &st);
    let mut st = Stats::default();
    for i in 0..per_kind {
        load_case(
            &mut st,
            &format!("random bytes, case {i}"),
            random_bytes(&mut rng),
        );
    }
    report("onnx random bytes", &st);
}

#[test]
fn onnx_loader_never_panics_hangs_or_allocates_without_bound() {
    fuzz_onnx(2000, 1);
}

#[test]
#[ignore = "10,000 cases per kind; run in release with --ignored --nocapture"]
fn onnx_loader_fuzz_10k() {
    fuzz_onnx(10_000, 2);
}

#[test]
fn a_declared_dimension_of_2_pow_40_is_an_error_without_allocating() {
    use prost::Message;
    let b = std::fs::read(reference("base_model_denorm.onnx")).unwrap();
    let m = ModelProto::decode(b.as_slice()).unwrap();
    let mut a = m.clone();
    a.graph.as_mut().unwrap().initializer[0].dims = vec![1 << 40, 1 << 40];
    let e = samara_nn::onnx::from_bytes(&a.encode_to_vec(), "a.onnx").unwrap_err();
    assert!(e.to_string().contains("more than"), "{e}");
    let mut c = m.clone();
    for i in &mut c.graph.as_mut().unwrap().input {
        for d in &mut i
            .r#type
            .as_mut()
            .unwrap()
            .tensor_type
            .as_mut()
            .unwrap()
            .shape
            .as_mut()
            .unwrap()
            .dim
        {
            d.dim_value = Some(1 << 40);
        }
    }
    let e = samara_nn::onnx::from_bytes(&c.encode_to_vec(), "c.onnx").unwrap_err();
    assert!(e.to_string().contains("memory budget"), "{e}");
}

// ---------------------------------------------------------------- CSV and IDX

const SYNTH_CSV: &str = "a,b,c\n1,2,3\n-4.5,5e-3,6\n# comment\n\n7,8,9\n";

fn synth_idx() -> Vec<u8> {
    let mut b = vec![0, 0, 0x0D, 2, 0, 0, 0, 3, 0, 0, 0, 2];
    for v in [1.0f32, 2.0, 3.0, -4.0, 5.5, 6.0] {
        b.extend(v.to_be_bytes());
    }
    b
}

/// Bytes that matter to a CSV parser.
const CSV_BYTES: &[u8] = b",.-+e0123456789\n\r #naifNxE";

fn csv_flip(rng: &mut ChaCha8Rng, b: &[u8]) -> Vec<u8> {
    let mut v = b.to_vec();
    for _ in 0..rng.gen_range(1..=8) {
        if v.is_empty() {
            break;
        }
        let i = rng.gen_range(0..v.len());
        v[i] = if rng.gen_bool(0.8) {
            CSV_BYTES[rng.gen_range(0..CSV_BYTES.len())]
        } else {
            rng.gen()
        };
    }
    v
}

fn csv_case(st: &mut Stats, what: &str, bytes: Vec<u8>) {
    case(st, what, move || {
        let text = String::from_utf8_lossy(&bytes);
        match parse_csv(&text, "fuzz.csv") {
            Ok(t) => {
                assert!(t.rows() >= 1 && t.cols >= 1);
                let m = MinMax::of(&t);
                assert_eq!(m.min.len(), t.cols);
                true
            }
            Err(e) => {
                let s = e.to_string();
                assert!(s.starts_with("fuzz.csv") && !s.contains(":0:"), "{s}");
                false
            }
        }
    });
}

fn idx_case(st: &mut Stats, what: &str, bytes: Vec<u8>) {
    case(st, what, move || match parse_idx(&bytes, "fuzz.idx") {
        Ok(t) => {
            assert!(t.rows() >= 1 && t.cols >= 1);
            let _ = t.row(t.rows() - 1);
            true
        }
        Err(e) => {
            let s = e.to_string();
            assert!(s.starts_with("fuzz.idx: "), "{s}");
            false
        }
    });
}

/// An IDX header with a huge or zero dimension (or a changed rank or type byte).
fn idx_header(rng: &mut ChaCha8Rng, b: &[u8]) -> Vec<u8> {
    let mut v = b.to_vec();
    match rng.gen_range(0..3) {
        0 if v.len() >= 4 => v[3] = rng.gen(),
        1 if v.len() >= 4 => {
            v[2] = [0x08, 0x09, 0x0B, 0x0C, 0x0D, 0x0E, 0x00, 0xFF][rng.gen_range(0..8)]
        }
        _ => {
            let rank = v.get(3).copied().unwrap_or(0) as usize;
            if rank > 0 && v.len() >= 4 + 4 * rank {
                let k = rng.gen_range(0..rank);
                let d: u32 = [u32::MAX, 0, 1 << 31, 1 << 20, 1, rng.gen()][rng.gen_range(0..6)];
                v[4 + 4 * k..8 + 4 * k].copy_from_slice(&d.to_be_bytes());
            }
        }
    }
    v
}

fn fuzz_data(per_kind: usize, seed: u64) {
    start_watchdog();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut csvs: Vec<Vec<u8>> = [
        "Training_Data.csv",
        "Training_Data_Normalised.csv",
        "Normalisation_Constants.csv",
    ]
    .iter()
    .map(|f| std::fs::read(reference(f)).unwrap())
    .collect();
    csvs.push(SYNTH_CSV.as_bytes().to_vec());
    let mut idxs: Vec<Vec<u8>> = ["dataset_inputs.idx", "dataset_outputs.idx"]
        .iter()
        .map(|f| std::fs::read(reference(f)).unwrap())
        .collect();
    idxs.push(synth_idx());
    for c in &csvs {
        parse_csv(&String::from_utf8_lossy(c), "orig.csv").unwrap();
    }
    for b in &idxs {
        parse_idx(b, "orig.idx").unwrap();
    }
    type Mut = fn(&mut ChaCha8Rng, &[u8]) -> Vec<u8>;
    let csv_kinds: [(&str, Mut); 4] = [
        ("csv character flips", csv_flip),
        ("csv byte flips", flip),
        ("csv truncations", truncate),
        ("csv insertions", insert),
    ];
    for (kind, m) in csv_kinds {
        let mut st = Stats::default();
        for i in 0..per_kind {
            // The small synthetic file every other case: it is cheap and dense in edge cases.
            let k = if i % 2 == 0 {
                csvs.len() - 1
            } else {
                i / 2 % csvs.len()
            };
            csv_case(&mut st, &format!("{kind}, case {i}"), m(&mut rng, &csvs[k]));
        }
        report(kind, &st);
    }
    let mut st = Stats::default();
    for i in 0..per_kind {
        csv_case(
            &mut st,
            &format!("csv random, case {i}"),
            random_bytes(&mut rng),
        );
    }
    report("csv random bytes", &st);
    let idx_kinds: [(&str, Mut); 4] = [
        ("idx byte flips", flip),
        ("idx truncations", truncate),
        ("idx insertions", insert),
        ("idx huge/zero header", idx_header),
    ];
    for (kind, m) in idx_kinds {
        let mut st = Stats::default();
        for i in 0..per_kind {
            let k = i % idxs.len();
            idx_case(&mut st, &format!("{kind}, case {i}"), m(&mut rng, &idxs[k]));
        }
        report(kind, &st);
    }
    let mut st = Stats::default();
    for i in 0..per_kind {
        let mut b = random_bytes(&mut rng);
        if i % 2 == 0 && b.len() >= 2 {
            b[0] = 0;
            b[1] = 0;
        }
        idx_case(&mut st, &format!("idx random, case {i}"), b);
    }
    report("idx random bytes", &st);
}

#[test]
fn csv_and_idx_readers_never_panic_hang_or_allocate_without_bound() {
    fuzz_data(2000, 3);
}

#[test]
#[ignore = "10,000 cases per kind; run in release with --ignored --nocapture"]
fn csv_and_idx_fuzz_10k() {
    fuzz_data(10_000, 4);
}
