//! `--shard I/N`: the sweeping commands compute only their share and write it as a shard
//! file (`samara merge`, in `merge.rs`, puts them back together). The shard files, their
//! digests and checks are `samara_app::shard`'s.

use anyhow::Result;
pub use samara_app::shard::{digest, digest_inputs, resolved, Shard};
use serde::Serialize;
use std::path::Path;

/// Write a shard file: the document and its payload digest.
pub fn write(
    out: &Path,
    kind: &str,
    shard: Shard,
    run: &impl Serialize,
    result: &impl Serialize,
) -> Result<()> {
    let text = samara_app::shard::document(kind, shard, run, result)?;
    samara_report::write_atomic(out, text.as_bytes())
        .map_err(|e| anyhow::anyhow!("--out {}: {e}", out.display()))
}
