//! `samara merge`: the shards' partial results of a `--shard I/N` run put back together
//! into what one process writes, so a Slurm or Kubernetes job array needs no glue script.

use anyhow::{bail, Result};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

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
    let shards = samara_app::shard::read_shards(a.kind.name(), &a.files)?;
    match a.kind {
        Kind::Robustness => crate::verify::merge_robustness(&shards, a.out.as_deref(), a.json),
        Kind::Vnncomp => {
            let Some(out) = &a.out else {
                bail!("--out FILE is required for `samara merge vnncomp` (the results CSV)");
            };
            crate::vnncomp::merge_vnncomp(&shards, out, a.json)
        }
        Kind::Reach => {
            let Some(out) = &a.out else {
                bail!("--out DIR is required for `samara merge reach` (the folder of reach.json and the figures)");
            };
            if samara_app::reach::system::is_taylor(&shards.run) {
                crate::reach_system::merge_shards(&shards, out, a.json)
            } else {
                crate::reach::merge_reach(&shards, out, a.json)
            }
        }
    }
}
