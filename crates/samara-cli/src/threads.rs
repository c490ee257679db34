//! `--threads N`: the size of the worker pool, for every command that runs in parallel
//! (reach, verify, critical, robustness, verify-vnnlib, vnncomp). The engines give the
//! same verdicts whatever the count (their searches are batched in a fixed order).

use anyhow::{anyhow, bail, Result};

/// Most worker threads.
pub const MAX_THREADS: usize = 1024;

/// The `--threads` flag, flattened into a command's flags.
#[derive(clap::Args, Debug, Clone, Copy, Default)]
pub struct ThreadsArg {
    /// Worker threads, 1 to 1024 (default: all cores); the verdicts do not depend on it
    #[arg(long)]
    pub threads: Option<usize>,
}

/// Refuse 0 and more than [`MAX_THREADS`], naming the flag.
pub fn check(threads: Option<usize>) -> Result<()> {
    match threads {
        Some(0) => bail!("--threads 0: give at least 1 (or leave it out to use all cores)"),
        Some(n) if n > MAX_THREADS => bail!(
            "--threads {n}: at most {MAX_THREADS} worker threads are allowed (more than the cores only costs memory); leave it out to use all cores"
        ),
        _ => Ok(()),
    }
}

/// Check `--threads` and start the global worker pool with that many workers (all cores
/// without it).
pub fn start(threads: Option<usize>) -> Result<()> {
    check(threads)?;
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| anyhow!("--threads {n}: cannot start the thread pool: {e}"))?;
    }
    Ok(())
}
