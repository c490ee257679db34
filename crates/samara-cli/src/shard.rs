//! `--shard I/N` (the sweeping commands compute only their share) and `samara merge`
//! (the shards' partial results put back together into what one process writes), so a
//! Slurm or Kubernetes job array needs no glue script.
//!
//! A shard file is JSON: `{"format": "samara-shard/2", "kind", "shard": [I, N], "run",
//! "result", "digest"}`. `run` records the inputs (a content digest of every file the
//! whole run reads, not only this shard's share, and where relative paths were resolved)
//! and the settings; every shard of one run carries the same `run`, so a file edited
//! between two shards' runs is caught by the merge, which names the input or setting
//! that differs. `digest` is the digest of the rest of the document (its canonical
//! serde_json text: sorted keys, exact floats), so a shard edited or damaged after it was
//! written is refused. Numbers that must merge exactly are stored as their shortest
//! round-trip decimal text (`{:?}`), which `str::parse` reads back to the same f64.

use anyhow::{anyhow, bail, Result};
use serde_json::{json, Value};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// The shard-file format tag.
pub const FORMAT: &str = "samara-shard/2";

/// The format of shards written before inputs and payloads were digested: refused with
/// a message saying to run them again.
const OLD_FORMAT: &str = "samara-shard/1";

/// Shard `i` of `n` (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard's index, `0 <= i < n`.
    pub i: usize,
    /// The number of shards, `n >= 1`.
    pub n: usize,
}

/// clap's parser of `--shard I/N`: a bad value is a usage error (exit 2).
pub fn parse_shard(s: &str) -> Result<Shard, String> {
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

/// A 64-bit FNV-1a digest (hex) of a file's bytes: shards of one run must have read the
/// same inputs, wherever those were on each machine.
pub fn digest_file(path: &Path, flag: &str) -> Result<String> {
    let b =
        std::fs::read(path).map_err(|e| anyhow!("{flag} {}: cannot read: {e}", path.display()))?;
    Ok(digest(&b))
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

/// The exact text of an f64 (reads back to the same value).
pub fn f(x: f64) -> Value {
    Value::String(format!("{x:?}"))
}

/// Read back an [`f`] value.
pub fn get_f(v: &Value, key: &str, file: &Path) -> Result<f64> {
    v[key].as_str().and_then(|s| s.parse().ok()).ok_or_else(|| {
        anyhow!(
            "{}: `{key}` is missing or not a number text",
            file.display()
        )
    })
}

/// The payload digest of a shard document (everything but its `digest` field): the
/// digest of its canonical serde_json text (keys sorted, floats exact), which reading the
/// file back reproduces.
fn payload_digest(doc: &Value) -> Result<String> {
    let mut d = doc.clone();
    if let Some(m) = d.as_object_mut() {
        m.remove("digest");
    }
    Ok(digest(serde_json::to_string(&d)?.as_bytes()))
}

/// Write a shard file: the document and its payload digest.
pub fn write(out: &Path, kind: &str, shard: Shard, run: Value, result: Value) -> Result<()> {
    let mut doc = json!({"format": FORMAT, "kind": kind, "shard": [shard.i, shard.n],
        "run": run, "result": result});
    doc["digest"] = Value::String(payload_digest(&doc)?);
    samara_report::write_atomic(out, serde_json::to_string_pretty(&doc)?.as_bytes())
        .map_err(|e| anyhow!("--out {}: {e}", out.display()))
}

/// The digests of the files a run reads, keyed by how the run names them (a path relative
/// to the run's root, or a flag): `run.inputs` of the shard files. A file is read once
/// however many instances use it.
pub fn digest_inputs<'a>(
    files: impl IntoIterator<Item = (String, &'a Path, String)>,
) -> Result<Value> {
    let mut m = serde_json::Map::new();
    for (name, path, flag) in files {
        if !m.contains_key(&name) {
            m.insert(name, Value::String(digest_file(path, &flag)?));
        }
    }
    Ok(Value::Object(m))
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
fn run_differences(a: &Value, b: &Value) -> Vec<String> {
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

/// Which command's shards are merged.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// `samara robustness --shard I/N --out FILE` outputs.
    Robustness,
    /// `samara vnncomp --shard I/N --out FILE` outputs.
    Vnncomp,
    /// `samara reach --shard I/N --out FILE` outputs.
    Reach,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Robustness => "robustness",
            Kind::Vnncomp => "vnncomp",
            Kind::Reach => "reach",
        }
    }
}

/// Merge the shard files of one sharded run into what one process writes.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  samara robustness --network n.onnx --data d.csv --shard 0/3 --out s0.json   # ... 1/3, 2/3\n  samara merge robustness s0.json s1.json s2.json --json\n  samara vnncomp instances.csv --shard $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT --out part-$SLURM_ARRAY_TASK_ID.json\n  samara merge vnncomp part-*.json --out results.csv\n  samara reach --network n.onnx --goal-ystar 2 --shard 0/4 --out r0.json   # ... 3/4\n  samara merge reach r0.json r1.json r2.json r3.json --out out/reach\n  samara reach --system s.sys --network n.onnx --grid theta=4 --shard 1/2 --out t1.json   # and 0/2\n  samara merge reach t0.json t1.json --out out/t\n\nExit codes: 0 merged (reach: proved or no goal, as `samara reach`), 1 reach: violated or unknown, 2 a usage or input error (a missing or duplicate shard, shards of different runs, a bad file, a reach run that cannot be merged exactly)."
)]
pub struct MergeArgs {
    /// The command whose shards these are.
    #[arg(value_enum)]
    pub kind: Kind,
    /// The N shard files (any order).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Output: robustness, the per-point CSV file (optional); vnncomp, the results CSV
    /// file (required); reach, the output folder of reach.json and the figures (required).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// JSON output on stdout (as the unsharded command's --json).
    #[arg(long)]
    pub json: bool,
}

/// Read and check the shard files: the same kind and run, N files for shards 0..N each
/// once. Returns the `result`s in shard order, with their files.
fn read_shards(a: &MergeArgs) -> Result<(Value, Vec<(PathBuf, Value)>)> {
    let mut docs: Vec<(PathBuf, Value)> = Vec::new();
    for p in &a.files {
        let text =
            std::fs::read_to_string(p).map_err(|e| anyhow!("{}: cannot read: {e}", p.display()))?;
        let v: Value = serde_json::from_str(&text)
            .map_err(|e| anyhow!("{}: not a shard file (JSON: {e})", p.display()))?;
        if v["format"] == OLD_FORMAT {
            bail!(
                "{}: a shard written by an older samara ({OLD_FORMAT}: without digests of its inputs and payload); run the shards again with this samara",
                p.display()
            );
        }
        if v["format"] != FORMAT {
            bail!(
                "{}: not a shard file (no \"format\": \"{FORMAT}\"); write shards with --shard I/N --out FILE",
                p.display()
            );
        }
        if v["kind"] != a.kind.name() {
            bail!(
                "{}: a {} shard, not {}",
                p.display(),
                v["kind"],
                a.kind.name()
            );
        }
        let recorded = v["digest"].as_str().unwrap_or("none").to_string();
        let computed = payload_digest(&v)?;
        if recorded != computed {
            bail!(
                "{}: the shard's payload digest does not match its contents (recorded {recorded}, computed {computed}): the file was edited or damaged after shard {}/{} wrote it; run that shard again",
                p.display(),
                v["shard"][0],
                v["shard"][1]
            );
        }
        docs.push((p.clone(), v));
    }
    let (first, d0) = &docs[0];
    let n = d0["shard"][1]
        .as_u64()
        .ok_or_else(|| anyhow!("{}: bad \"shard\"", first.display()))? as usize;
    let mut by: Vec<Vec<&Path>> = vec![Vec::new(); n];
    for (p, d) in &docs {
        if d["run"] != d0["run"] {
            bail!(
                "{} and {}: shards of different runs: {}; run every shard on the same inputs and settings",
                first.display(),
                p.display(),
                run_differences(&d0["run"], &d["run"]).join("; ")
            );
        }
        let (i, m) = (d["shard"][0].as_u64(), d["shard"][1].as_u64());
        match (i, m) {
            (Some(i), Some(m)) if m as usize == n && (i as usize) < n => by[i as usize].push(p),
            _ => bail!(
                "{}: shard {} of a {}-shard run mixed with a {n}-shard run ({})",
                p.display(),
                d["shard"][0],
                d["shard"][1],
                first.display()
            ),
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
        bail!(
            "duplicate shard(s): {}; pass each shard once",
            dups.join("; ")
        );
    }
    if !missing.is_empty() {
        bail!(
            "missing shard(s): {} of {n}; run them (--shard I/{n}) and pass all {n} files",
            missing.join(", ")
        );
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
    let ordered = ordered.into_iter().map(|(_, p, r)| (p, r)).collect();
    Ok((run, ordered))
}

/// Run `samara merge`.
pub fn run_merge(a: &MergeArgs) -> Result<ExitCode> {
    if let Some(o) = &a.out {
        let refs: Vec<(&str, &Path)> = a
            .files
            .iter()
            .map(|p| ("a shard file", p.as_path()))
            .collect();
        if a.kind == Kind::Reach {
            samara_report::guard::check_output_dir("--out", o, &crate::reach::WRITES, &refs)?;
        } else {
            samara_report::guard::check_output_file("--out", o, &refs)?;
        }
    }
    let (run, shards) = read_shards(a)?;
    match a.kind {
        Kind::Robustness => super::merge_robustness(&run, &shards, a.out.as_deref(), a.json),
        Kind::Vnncomp => {
            let Some(out) = &a.out else {
                bail!("--out FILE is required for `samara merge vnncomp` (the results CSV)");
            };
            super::vnncomp::merge_vnncomp(&run, &shards, out, a.json)
        }
        Kind::Reach => {
            let Some(out) = &a.out else {
                bail!("--out DIR is required for `samara merge reach` (the folder of reach.json and the figures)");
            };
            if run["sets"] == "taylor" {
                crate::reach_system::merge_shards(&run, &shards, out, a.json)
            } else {
                crate::reach::merge_reach(&run, &shards, out, a.json)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let before = payload_digest(&d).unwrap();
        d["digest"] = json!("anything");
        assert_eq!(payload_digest(&d).unwrap(), before);
        // Read back from its text, the same digest.
        let back: Value = serde_json::from_str(&serde_json::to_string_pretty(&d).unwrap()).unwrap();
        assert_eq!(payload_digest(&back).unwrap(), before);
        d["result"][0] = json!(3);
        assert_ne!(payload_digest(&d).unwrap(), before);
    }
}
