//! `--threads N`: the size of the worker pool, for every command that runs in parallel
//! (reach, verify, critical, robustness, verify-vnnlib, vnncomp). The engines give the
//! same verdicts whatever the count (their searches are batched in a fixed order).

use anyhow::{anyhow, Result};

/// Check `--threads` and start the global worker pool with that many workers (all cores
/// without it).
pub fn start(threads: Option<usize>) -> Result<()> {
    samara_app::reach::args::check_threads(threads)?;
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| anyhow!("--threads {n}: cannot start the thread pool: {e}"))?;
    }
    Ok(())
}
