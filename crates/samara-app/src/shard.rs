//! Shard files: the partial results of a `--shard I/N` run (the sweeping commands
//! compute only their share) and their checks before `samara merge` puts them back
//! together into what one process writes.
//!
//! A shard file is JSON: `{"format": "samara-shard/2", "kind", "shard": [I, N], "run",
//! "result", "digest"}`. `run` records the inputs (a content digest of every file the
//! whole run reads, not only this shard's share, and where relative paths were resolved)
//! and the settings; every shard of one run carries the same `run`, so a file edited
//! between two shards' runs is caught by the merge, which names the input or setting
//! that differs. `digest` is the digest of the rest of the document (its canonical
//! serde_json text: sorted keys, exact floats), so a shard edited or damaged after it was
//! written is refused. Numbers that must merge exactly are [`Exact`]: their shortest
//! round-trip decimal text (`{:?}`), which reads back to the same f64, infinities and
//! NaN included.

use crate::AppError;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use serde_json::Value;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The shard-file format tag.
pub const FORMAT: &str = "samara-shard/2";

/// The format of shards written before inputs and payloads were digested: refused with
/// a message saying to run them again.
const OLD_FORMAT: &str = "samara-shard/1";

type Result<T> = std::result::Result<T, AppError>;

fn bad<T>(m: String) -> Result<T> {
    Err(AppError::Input(m))
}

/// Shard `i` of `n` (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Shard {
    /// This shard's index, `0 <= i < n`.
    pub i: usize,
    /// The number of shards, `n >= 1`.
    pub n: usize,
}

/// Parse `I/N` (clap's parser of `--shard`; a bad value is a usage error).
pub fn parse_shard(s: &str) -> std::result::Result<Shard, String> {
    let bad = |why: &str| {
        format!("{why}; expected I/N with 0 <= I < N (0-based, e.g. --shard 0/4 ... --shard 3/4; a Slurm array: --shard $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT)")
    };
    let (i, n) = s
        .split_once('/')
        .ok_or_else(|| bad(&format!("`{s}` has no `/`")))?;
    let i: usize = i
        .trim()
        .parse()
        .map_err(|_| bad(&format!("I `{i}` is not a whole number")))?;
    let n: usize = n
        .trim()
        .parse()
        .map_err(|_| bad(&format!("N `{n}` is not a whole number")))?;
    if n == 0 {
        return Err(bad("N is 0"));
    }
    if i >= n {
        return Err(bad(&format!("I = {i} is not below N = {n}")));
    }
    Ok(Shard { i, n })
}

impl Shard {
    /// This shard's contiguous part of `0..len` (the parts of `0..n` cover it in order,
    /// sizes differ by at most one; a part may be empty when `n > len`).
    pub fn range(&self, len: usize) -> Range<usize> {
        (self.i * len / self.n)..((self.i + 1) * len / self.n)
    }
}

/// An f64 stored as its exact text (`{:?}`, e.g. `"0.1"`, `"inf"`, `"NaN"`), which reads
/// back to the same value bit for bit: what shard files hold where a merge must
/// reproduce one process's numbers, non-finite ones included (JSON numbers cannot say
/// infinity; serde_json would write `null`).
#[derive(Clone, Copy, Debug)]
pub struct Exact(pub f64);

impl PartialEq for Exact {
    /// The same bits (so a NaN equals itself, as the text it came from).
    fn eq(&self, o: &Exact) -> bool {
        self.0.to_bits() == o.0.to_bits()
    }
}

impl Serialize for Exact {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(&format!("{:?}", self.0))
    }
}

impl<'de> Deserialize<'de> for Exact {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Exact, D::Error> {
        let t = String::deserialize(d)?;
        t.parse()
            .map(Exact)
            .map_err(|_| serde::de::Error::custom(format!("expected a number text, found {t:?}")))
    }
}

/// An f64 of a shard's result that a merge must get back bit for bit, written as a JSON
/// number when finite (the very bytes serde_json writes for an f64, read back exactly:
/// the workspace's serde_json has `float_roundtrip`) and as its text otherwise
/// (`"inf"`, `"-inf"`, `"NaN"`), where serde_json would write `null` and lose the value.
/// Unlike [`Exact`], a result whose numbers are all finite keeps the bytes of plain
/// f64s.
#[derive(Clone, Copy, Debug)]
pub struct Float(pub f64);

impl PartialEq for Float {
    /// The same bits (so a NaN equals itself, as the text it came from).
    fn eq(&self, o: &Float) -> bool {
        self.0.to_bits() == o.0.to_bits()
    }
}

impl Serialize for Float {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        if self.0.is_finite() {
            s.serialize_f64(self.0)
        } else {
            s.serialize_str(&format!("{:?}", self.0))
        }
    }
}

impl<'de> Deserialize<'de> for Float {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Float, D::Error> {
        struct Visit;
        impl serde::de::Visitor<'_> for Visit {
            type Value = Float;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number, or \"inf\", \"-inf\" or \"NaN\"")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> std::result::Result<Float, E> {
                Ok(Float(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> std::result::Result<Float, E> {
                Ok(Float(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> std::result::Result<Float, E> {
                Ok(Float(v as f64))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> std::result::Result<Float, E> {
                match v {
                    "inf" => Ok(Float(f64::INFINITY)),
                    "-inf" => Ok(Float(f64::NEG_INFINITY)),
                    "NaN" => Ok(Float(f64::NAN)),
                    _ => Err(E::invalid_value(serde::de::Unexpected::Str(v), &self)),
                }
            }
        }
        d.deserialize_any(Visit)
    }
}

/// An interval as two [`Exact`] ends.
pub type ExactPair = [Exact; 2];

/// `[lo, hi]` as an [`ExactPair`].
pub fn pair(v: [f64; 2]) -> ExactPair {
    [Exact(v[0]), Exact(v[1])]
}

/// An [`ExactPair`] read back.
pub fn unpair(v: ExactPair) -> [f64; 2] {
    [v[0].0, v[1].0]
}

/// A 64-bit FNV-1a digest (hex) of a file's bytes: shards of one run must have read the
/// same inputs, wherever those were on each machine. `flag` names the file in messages.
pub fn digest_file(path: &Path, flag: &str) -> Result<String> {
    match std::fs::read(path) {
        Ok(b) => Ok(digest(&b)),
        Err(e) => bad(format!("{flag} {}: cannot read: {e}", path.display())),
    }
}

/// A 64-bit FNV-1a digest (hex) of bytes.
pub fn digest(b: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for x in b {
        h ^= u64::from(*x);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// The payload digest of a shard document (everything but its `digest` field): the
/// digest of its canonical serde_json text (keys sorted, floats exact), which reading the
/// file back reproduces.
fn payload_digest(doc: &Value) -> String {
    let mut d = doc.clone();
    if let Some(m) = d.as_object_mut() {
        m.remove("digest");
    }
    digest(d.to_string().as_bytes())
}

fn json(v: &impl Serialize) -> Result<Value> {
    serde_json::to_value(v).map_err(|e| AppError::Input(format!("shard: {e}")))
}

/// A shard file: what one shard of a `--shard I/N` run writes.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ShardFile<R, T> {
    /// [`FORMAT`].
    pub format: String,
    /// The command: `robustness`, `vnncomp` or `reach`.
    pub kind: String,
    /// `[I, N]`.
    pub shard: (usize, usize),
    /// The inputs and settings every shard of the run shares.
    pub run: R,
    /// This shard's part of the result.
    pub result: T,
    /// The payload digest (of everything else).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub digest: Option<String>,
}

/// The text of a shard file of `kind` (`robustness`, `vnncomp`, `reach`): the document
/// with its payload digest, pretty-printed with sorted keys.
pub fn document(
    kind: &str,
    shard: Shard,
    run: &impl Serialize,
    result: &impl Serialize,
) -> Result<String> {
    let file = ShardFile {
        format: FORMAT.into(),
        kind: kind.into(),
        shard: (shard.i, shard.n),
        run,
        result,
        digest: None,
    };
    let mut doc = json(&file)?;
    doc["digest"] = Value::String(payload_digest(&doc));
    Ok(serde_json::to_string_pretty(&doc).expect("a JSON value prints"))
}

/// Write the shard file `out` of `kind` ([`document`]); a write error names `--out`.
pub fn write(
    out: &Path,
    kind: &str,
    shard: Shard,
    run: &impl Serialize,
    result: &impl Serialize,
) -> anyhow::Result<()> {
    let text = document(kind, shard, run, result)?;
    samara_report::write_atomic(out, text.as_bytes())
        .map_err(|e| anyhow::anyhow!("--out {}: {e}", out.display()))
}

/// The digests of the files a run reads, keyed by how the run names them (a path
/// relative to the run's root, or a flag; `(name, path, flag for messages)`): `run.inputs`
/// of the shard files. A file is read once however many instances use it.
pub fn digest_inputs<'a>(
    files: impl IntoIterator<Item = (String, &'a Path, String)>,
) -> Result<std::collections::BTreeMap<String, String>> {
    let mut m = std::collections::BTreeMap::new();
    for (name, path, flag) in files {
        if let std::collections::btree_map::Entry::Vacant(e) = m.entry(name) {
            e.insert(digest_file(path, &flag)?);
        }
    }
    Ok(m)
}

/// A path made absolute (the current folder joined to a relative one) and, where it
/// exists, canonical: the `--root` a run resolved its relative paths against.
pub fn resolved(p: &Path) -> String {
    let p = if p.as_os_str().is_empty() {
        Path::new(".")
    } else {
        p
    };
    let abs = std::fs::canonicalize(p).unwrap_or_else(|_| {
        std::env::current_dir()
            .map(|d| d.join(p))
            .unwrap_or_else(|_| p.to_path_buf())
    });
    abs.display().to_string()
}

/// A JSON value in a message: strings without their quotes.
fn show(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        Value::Null => "none".into(),
        v => v.to_string(),
    }
}

/// Where two shards' `run` records differ, one phrase each: `input `NAME` (content
/// digest A vs B)` for a file under `inputs`, `setting `PATH` (A vs B)` otherwise.
pub fn run_differences(a: &Value, b: &Value) -> Vec<String> {
    fn walk(a: &Value, b: &Value, path: &str, out: &mut Vec<String>) {
        if a == b {
            return;
        }
        match (a, b) {
            (Value::Object(x), Value::Object(y)) => {
                let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
                keys.sort();
                keys.dedup();
                for k in keys {
                    let p = if path.is_empty() {
                        k.clone()
                    } else {
                        format!("{path}.{k}")
                    };
                    let (va, vb) = (
                        x.get(k).unwrap_or(&Value::Null),
                        y.get(k).unwrap_or(&Value::Null),
                    );
                    // Reach's Taylor-model shards record their file digests as
                    // `run.network` and `run.system`.
                    if path == "inputs" || (path.is_empty() && (k == "network" || k == "system")) {
                        if va != vb {
                            let word = if va.is_null() || vb.is_null() {
                                "read by one shard only"
                            } else {
                                "changed between the shards' runs"
                            };
                            out.push(format!(
                                "input `{k}` {word} (content digest {} vs {})",
                                show(va),
                                show(vb)
                            ));
                        }
                    } else {
                        walk(va, vb, &p, out);
                    }
                }
            }
            _ => out.push(format!("setting `{path}` ({} vs {})", show(a), show(b))),
        }
    }
    let mut out = Vec::new();
    walk(a, b, "", &mut out);
    out
}

/// Shard files read and checked: the run every shard shares and each shard's `result`
/// with its file, in shard order.
#[derive(Debug)]
pub struct Shards {
    /// The `run` record (the same in every file).
    pub run: Value,
    /// `(file, result)` of shards `0..N`.
    pub results: Vec<(PathBuf, Value)>,
}

impl Shards {
    /// The `run` record as the type `T` (a [`Value`] stays one).
    pub fn run_as<T: serde::de::DeserializeOwned>(&self) -> Result<T> {
        serde_json::from_value(self.run.clone()).or_else(|e| {
            bad(format!(
                "shard files: the `run` record is not one this samara writes: {e}"
            ))
        })
    }

    /// Each shard's `result` as the type `T`, with its file.
    pub fn results_as<T: serde::de::DeserializeOwned>(&self) -> Result<Vec<(PathBuf, T)>> {
        self.results
            .iter()
            .map(|(p, v)| match serde_json::from_value(v.clone()) {
                Ok(t) => Ok((p.clone(), t)),
                Err(e) => bad(format!(
                    "{}: the shard's `result` is not one this samara writes: {e}",
                    p.display()
                )),
            })
            .collect()
    }
}

/// Read and check the shard `files` of `kind`: the same kind and run, N files for shards
/// 0..N each once, every payload digest intact.
pub fn read_shards(kind: &str, files: &[PathBuf]) -> Result<Shards> {
    let mut texts = Vec::with_capacity(files.len());
    for p in files {
        match std::fs::read_to_string(p) {
            Ok(t) => texts.push((p.clone(), t)),
            Err(e) => return bad(format!("{}: cannot read: {e}", p.display())),
        }
    }
    read_shard_texts(kind, texts)
}

/// [`read_shards`] of documents already read (`(name for messages, text)`; Python's
/// `samara.distributed` holds its shards' documents in memory).
pub fn read_shard_texts(kind: &str, texts: Vec<(PathBuf, String)>) -> Result<Shards> {
    let mut docs: Vec<(PathBuf, Value)> = Vec::new();
    for (p, text) in &texts {
        let v: Value = match serde_json::from_str(text) {
            Ok(v) => v,
            Err(e) => return bad(format!("{}: not a shard file (JSON: {e})", p.display())),
        };
        if v["format"] == OLD_FORMAT {
            return bad(format!(
                "{}: a shard written by an older samara ({OLD_FORMAT}: without digests of its inputs and payload); run the shards again with this samara",
                p.display()
            ));
        }
        if v["format"] != FORMAT {
            return bad(format!(
                "{}: not a shard file (no \"format\": \"{FORMAT}\"); write shards with --shard I/N --out FILE",
                p.display()
            ));
        }
        if v["kind"] != kind {
            return bad(format!(
                "{}: a {} shard, not {kind}",
                p.display(),
                v["kind"]
            ));
        }
        let recorded = v["digest"].as_str().unwrap_or("none").to_string();
        let computed = payload_digest(&v);
        if recorded != computed {
            return bad(format!(
                "{}: the shard's payload digest does not match its contents (recorded {recorded}, computed {computed}): the file was edited or damaged after shard {}/{} wrote it; run that shard again",
                p.display(),
                v["shard"][0],
                v["shard"][1]
            ));
        }
        docs.push((p.clone(), v));
    }
    let Some((first, d0)) = docs.first() else {
        return bad("no shard files given".into());
    };
    let Some(n) = d0["shard"][1].as_u64().map(|n| n as usize) else {
        return bad(format!("{}: bad \"shard\"", first.display()));
    };
    let mut by: Vec<Vec<&Path>> = vec![Vec::new(); n];
    for (p, d) in &docs {
        if d["run"] != d0["run"] {
            return bad(format!(
                "{} and {}: shards of different runs: {}; run every shard on the same inputs and settings",
                first.display(),
                p.display(),
                run_differences(&d0["run"], &d["run"]).join("; ")
            ));
        }
        match (d["shard"][0].as_u64(), d["shard"][1].as_u64()) {
            (Some(i), Some(m)) if m as usize == n && (i as usize) < n => by[i as usize].push(p),
            _ => {
                return bad(format!(
                    "{}: shard {} of a {}-shard run mixed with a {n}-shard run ({})",
                    p.display(),
                    d["shard"][0],
                    d["shard"][1],
                    first.display()
                ))
            }
        }
    }
    let missing: Vec<String> = (0..n)
        .filter(|i| by[*i].is_empty())
        .map(|i| format!("{i}/{n}"))
        .collect();
    let dups: Vec<String> = (0..n)
        .filter(|i| by[*i].len() > 1)
        .map(|i| {
            let fs: Vec<String> = by[i].iter().map(|p| p.display().to_string()).collect();
            format!("{i}/{n} ({})", fs.join(", "))
        })
        .collect();
    if !dups.is_empty() {
        return bad(format!(
            "duplicate shard(s): {}; pass each shard once",
            dups.join("; ")
        ));
    }
    if !missing.is_empty() {
        return bad(format!(
            "missing shard(s): {} of {n}; run them (--shard I/{n}) and pass all {n} files",
            missing.join(", ")
        ));
    }
    let run = d0["run"].clone();
    let mut ordered: Vec<(usize, PathBuf, Value)> = docs
        .into_iter()
        .map(|(p, mut d)| {
            let i = d["shard"][0].as_u64().unwrap_or(0) as usize;
            (i, p, d["result"].take())
        })
        .collect();
    ordered.sort_by_key(|(i, _, _)| *i);
    let results = ordered.into_iter().map(|(_, p, r)| (p, r)).collect();
    Ok(Shards { run, results })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn shards_cover_in_order() {
        for len in [0, 1, 5, 359] {
            for n in 1..7 {
                let mut next = 0;
                for i in 0..n {
                    let r = Shard { i, n }.range(len);
                    assert_eq!(r.start, next);
                    next = r.end;
                }
                assert_eq!(next, len);
            }
        }
        assert!(parse_shard("3/3").is_err());
        assert!(parse_shard("0/0").is_err());
        assert!(parse_shard("-1/3").is_err());
        assert!(parse_shard("1").is_err());
        assert_eq!(parse_shard("2/3"), Ok(Shard { i: 2, n: 3 }));
    }

    #[test]
    fn run_differences_name_the_input_or_setting() {
        let a =
            json!({"inputs": {"a.onnx": "01", "p.vnnlib": "02"}, "goal": {"ystar": "2.0"}, "n": 3});
        let b = json!({"inputs": {"a.onnx": "01", "p.vnnlib": "03", "q.vnnlib": "04"}, "goal": {"ystar": "2.5"}, "n": 3});
        assert_eq!(
            run_differences(&a, &b),
            [
                "setting `goal.ystar` (2.0 vs 2.5)",
                "input `p.vnnlib` changed between the shards' runs (content digest 02 vs 03)",
                "input `q.vnnlib` read by one shard only (content digest none vs 04)",
            ]
        );
        assert!(run_differences(&a, &a).is_empty());
    }

    #[test]
    fn payload_digest_ignores_only_the_digest_field() {
        let mut d = json!({"format": FORMAT, "run": {"x": "1.5"}, "result": [1, 2]});
        let before = payload_digest(&d);
        d["digest"] = json!("anything");
        assert_eq!(payload_digest(&d), before);
        // Read back from its text, the same digest.
        let back: Value = serde_json::from_str(&serde_json::to_string_pretty(&d).unwrap()).unwrap();
        assert_eq!(payload_digest(&back), before);
        d["result"][0] = json!(3);
        assert_ne!(payload_digest(&d), before);
    }

    #[test]
    fn exact_numbers_read_back_bit_for_bit_non_finite_included() {
        let xs = [
            0.1,
            -0.0,
            1.0 / 3.0,
            f64::MIN_POSITIVE,
            f64::MAX,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        let text = serde_json::to_string(&xs.map(Exact)).unwrap();
        assert_eq!(
            text,
            r#"["0.1","-0.0","0.3333333333333333","2.2250738585072014e-308","1.7976931348623157e308","inf","-inf","NaN"]"#
        );
        let back: Vec<Exact> = serde_json::from_str(&text).unwrap();
        for (x, b) in xs.iter().zip(&back) {
            assert_eq!(x.to_bits(), b.0.to_bits(), "{x:?}");
        }
        let e = serde_json::from_str::<Exact>("\"0.1x\"").unwrap_err();
        assert!(e.to_string().contains("expected a number text"), "{e}");
        // A JSON number is not an exact text.
        assert!(serde_json::from_str::<Exact>("0.1").is_err());
    }

    #[test]
    fn floats_keep_finite_bytes_and_read_back_bit_for_bit_non_finite_included() {
        let finite = [0.1, -0.0, 1.0 / 3.0, f64::MIN_POSITIVE, f64::MAX, 2.0];
        // Finite numbers: the bytes of a plain f64, so such shards are unchanged.
        assert_eq!(
            serde_json::to_string(&finite.map(Float)).unwrap(),
            serde_json::to_string(&finite).unwrap()
        );
        let odd = [f64::INFINITY, f64::NEG_INFINITY, f64::NAN];
        assert_eq!(
            serde_json::to_string(&odd.map(Float)).unwrap(),
            r#"["inf","-inf","NaN"]"#
        );
        // Through a JSON value, as shard files are read and written.
        let xs: Vec<Float> = finite.iter().chain(&odd).map(|x| Float(*x)).collect();
        let v = serde_json::to_value(&xs).unwrap();
        let back: Vec<Float> = serde_json::from_value(v).unwrap();
        for (x, b) in xs.iter().zip(&back) {
            assert_eq!(x.0.to_bits(), b.0.to_bits(), "{x:?}");
        }
        let e = serde_json::from_str::<Float>("\"infinity\"").unwrap_err();
        assert!(
            e.to_string().contains("\"inf\", \"-inf\" or \"NaN\""),
            "{e}"
        );
        assert!(serde_json::from_str::<Float>("null").is_err());
    }
}
