//! `samara vnncomp` and `samara merge vnncomp`: a whole VNN-COMP benchmark (its
//! instances CSV) as one run: the record its shards share, the results CSV and the
//! closing summary. Deciding one instance is [`crate::vnncomp`]'s.

use crate::args::VnncompArgs;
use crate::vnncomp::{InstanceResult, Line, VnncompRun, Word};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The results CSV's header.
pub const HEADER: &str = "onnx,vnnlib,timeout,result,seconds,engine,detail\n";

impl VnncompRun {
    /// The `run` record of a sharded `samara vnncomp`: the digest of the instances CSV
    /// (`text`, read from `a.instances`), and of every network and property file of all
    /// its lines (`all`, resolved against `root`), with the settings.
    pub fn of(a: &VnncompArgs, text: &str, all: &[Line], root: &Path) -> anyhow::Result<Self> {
        let files: Vec<(String, PathBuf, String)> = all
            .iter()
            .flat_map(|l| {
                let at = format!("{}:{}:", a.instances.display(), l.lineno);
                [
                    (l.onnx.clone(), root.join(&l.onnx), format!("{at} onnx")),
                    (
                        l.vnnlib.clone(),
                        root.join(&l.vnnlib),
                        format!("{at} vnnlib"),
                    ),
                ]
            })
            .collect();
        Ok(VnncompRun {
            instances: crate::shard::digest(text.as_bytes()),
            instances_file: crate::shard::resolved(&a.instances),
            n_instances: all.len(),
            root: crate::shard::resolved(root),
            inputs: crate::shard::digest_inputs(
                files
                    .iter()
                    .map(|(n, p, f)| (n.clone(), p.as_path(), f.clone())),
            )?,
            timeout_scale: format!("{:?}", a.timeout_scale),
            max_nodes: a.max_nodes,
        })
    }
}

/// The instances of a benchmark run (or merged shards) so far: the results CSV, the
/// counts by result word, and every instance's `--json` row as it was serialised (so
/// merged shards print the same numbers digit for digit).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Tally {
    /// The results CSV, header included.
    pub csv: String,
    /// Instances by result word.
    pub counts: BTreeMap<Word, usize>,
    /// Each instance's `--json` row, serialised.
    pub rows: Vec<String>,
}

impl Tally {
    /// An empty tally (the CSV's header only).
    pub fn new() -> Self {
        Tally {
            csv: HEADER.to_string(),
            ..Default::default()
        }
    }

    /// Count one instance's result (`csv`: whether it goes into the results CSV too).
    pub fn add(&mut self, part: &InstanceResult, csv: bool) -> serde_json::Result<()> {
        *self.counts.entry(part.result).or_default() += 1;
        if csv {
            self.csv.push_str(&part.csv_line());
        }
        self.rows
            .push(serde_json::to_string(&serde_json::to_value(part.row())?)?);
        Ok(())
    }

    /// The counts keyed by the word's text.
    pub fn word_counts(&self) -> BTreeMap<&'static str, usize> {
        self.counts.iter().map(|(w, n)| (w.text(), *n)).collect()
    }

    /// The closing summary on stdout: with `json`, every instance's row and the counts
    /// (in serde_json's sorted-key compact form), else one line.
    pub fn summary(&self, total: f64, out: &Path, json: bool) -> serde_json::Result<String> {
        if json {
            return Ok(format!(
                "{{\"counts\":{},\"instances\":[{}],\"out\":{},\"total_seconds\":{}}}",
                serde_json::to_string(&self.word_counts())?,
                self.rows.join(","),
                serde_json::to_string(out)?,
                serde_json::to_string(&total)?
            ));
        }
        let words: Vec<String> = [Word::Unsat, Word::Sat, Word::Timeout, Word::Unknown]
            .iter()
            .map(|w| format!("{} {}", w.text(), self.counts.get(w).copied().unwrap_or(0)))
            .collect();
        Ok(format!(
            "{} instances: {}; {total:.1} s in all; results in {}",
            self.rows.len(),
            words.join(", "),
            out.display()
        ))
    }
}
