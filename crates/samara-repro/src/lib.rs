//! `samara reproduce`: the whole Alsomitra case study in one command, from nothing but
//! the repository. Each stage writes its files atomically and records its result in a
//! cache keyed by its inputs, so an interrupted run leaves no half-written report and a
//! re-run reuses what is finished. The report (`report.md`, `report.html`) and
//! `results.json` are written last.

pub mod cache;
pub mod doc;
mod more;
pub mod stages;

use cache::Cache;
use doc::{Block, Document};
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of a reproduction run.
#[derive(Clone, Debug)]
pub struct ReproduceOptions {
    /// Output directory (created).
    pub out: PathBuf,
    /// A smaller run (fewer epochs, fewer samples) that finishes in under a minute.
    pub quick: bool,
    /// A directory laid out like the published `reference/` folder, to put the
    /// published data and networks beside samara's own.
    pub published: Option<PathBuf>,
    /// Ignore cached stage results.
    pub fresh: bool,
    /// Show progress bars on stderr.
    pub progress: bool,
    /// The command line, recorded in the report.
    pub command_line: String,
}

/// Errors of a reproduction run.
#[derive(Debug, thiserror::Error)]
pub enum ReproError {
    /// File system trouble.
    #[error("{path}: {message}")]
    Io {
        /// Path.
        path: PathBuf,
        /// Message with the fix.
        message: String,
    },
    /// A stage failed.
    #[error("stage `{stage}` failed: {message}")]
    Stage {
        /// Stage name.
        stage: String,
        /// What went wrong.
        message: String,
    },
}

/// What a stage hands back: JSON results, files written (relative to the output
/// directory), and report blocks.
pub struct StageOutput {
    /// Numbers for results.json.
    pub result: Value,
    /// Files written, relative to the output directory.
    pub files: Vec<String>,
}

/// Context shared by stages.
pub struct Ctx<'a> {
    /// Options.
    pub opts: &'a ReproduceOptions,
    /// Progress bars.
    pub bars: &'a MultiProgress,
}

impl Ctx<'_> {
    /// A progress bar of `len` steps with a message.
    pub fn bar(&self, len: u64, msg: &str) -> ProgressBar {
        let pb = self.bars.add(ProgressBar::new(len));
        pb.set_style(
            ProgressStyle::with_template("{spinner} {msg:28} [{bar:30}] {pos}/{len} {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        pb.set_message(msg.to_string());
        pb
    }

    /// Absolute path of an output file.
    pub fn path(&self, rel: &str) -> PathBuf {
        self.opts.out.join(rel)
    }
}

/// Outcome of a run.
#[derive(Debug)]
pub struct Outcome {
    /// Every number of the run.
    pub results: Value,
    /// Stages taken from the cache.
    pub reused: Vec<String>,
    /// Wall time.
    pub seconds: f64,
}

type StageFn = fn(&Ctx, &Value) -> Result<StageOutput, ReproError>;

/// Run the reproduction.
pub fn run(opts: &ReproduceOptions) -> Result<Outcome, ReproError> {
    let t0 = Instant::now();
    let io = |p: &Path, e: &dyn std::fmt::Display| ReproError::Io {
        path: p.to_path_buf(),
        message: format!("{e}; choose a writable --out"),
    };
    for sub in ["", "data", "figures", "networks", "tables"] {
        let p = opts.out.join(sub);
        std::fs::create_dir_all(&p).map_err(|e| io(&p, &e))?;
    }
    if let Some(p) = &opts.published {
        if !p.join("Training_Data.csv").exists() {
            return Err(ReproError::Io {
                path: p.clone(),
                message: "--published must point at a directory laid out like the published `reference/` folder (Training_Data.csv, *_norm.onnx, *_denorm.onnx)".into(),
            });
        }
    }
    let bars = MultiProgress::with_draw_target(if opts.progress {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    });
    let ctx = Ctx { opts, bars: &bars };
    let cache = Cache::new(&opts.out, opts.fresh);
    let version = env!("CARGO_PKG_VERSION");
    let mode = if opts.quick { "quick" } else { "full" };
    let published = opts
        .published
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_default();

    let stages: Vec<(&str, StageFn)> = stages::all();
    let mut results = serde_json::Map::new();
    let mut reused = Vec::new();
    let mut prev_key = String::new();
    let overall = ctx.bar(stages.len() as u64, "reproduce");
    for (name, f) in stages {
        overall.set_message(format!("stage {name}"));
        let key = cache::fnv1a(&[
            name,
            version,
            mode,
            &published,
            samara_train::CASE_STUDY_SPEC,
            &prev_key,
        ]);
        let res = if let Some(r) = cache.get(name, &key, &opts.out) {
            reused.push(name.to_string());
            r
        } else {
            let upstream = Value::Object(results.clone());
            let out = f(&ctx, &upstream)?;
            cache
                .put(name, &key, &out.files, &out.result)
                .map_err(|e| io(&opts.out.join(".cache"), &e))?;
            out.result
        };
        results.insert(name.to_string(), res);
        prev_key = key;
        overall.inc(1);
    }
    overall.finish_and_clear();
    let seconds = t0.elapsed().as_secs_f64();
    let results = Value::Object(results);
    let full = json!({
        "samara_version": version,
        "command_line": opts.command_line,
        "mode": mode,
        "seconds": seconds,
        "stages": results,
    });
    let doc = stages::report(&full, opts);
    // Refuse to publish a report that points at missing files.
    for img in doc.images() {
        if !opts.out.join(img).exists() {
            return Err(ReproError::Stage {
                stage: "report".into(),
                message: format!("figure {img} is missing"),
            });
        }
    }
    let w = |rel: &str, text: &str| {
        samara_report::write_atomic(&opts.out.join(rel), text.as_bytes())
            .map_err(|e| io(&opts.out.join(rel), &e))
    };
    w(
        "results.json",
        &serde_json::to_string_pretty(&full).unwrap_or_default(),
    )?;
    w("report.md", &doc.to_markdown())?;
    w("report.html", &doc.to_html())?;
    Ok(Outcome {
        results: full,
        reused,
        seconds,
    })
}

/// Helper for stages: a table block from rows of strings.
pub fn table(header: &[&str], rows: Vec<Vec<String>>) -> Block {
    Block::Table {
        header: header.iter().map(|s| s.to_string()).collect(),
        rows,
    }
}

/// Helper: an empty report document with the run's header.
pub fn new_report(full: &Value) -> Document {
    let mut d = Document::new("samara: the Alsomitra case study, reproduced");
    d.push(Block::Para(format!(
        "Produced by `{}` (samara {}, {} mode) in {:.1} s. Every number below is computed by this run; `results.json` holds them all.",
        full["command_line"].as_str().unwrap_or("samara reproduce"),
        full["samara_version"].as_str().unwrap_or("?"),
        full["mode"].as_str().unwrap_or("?"),
        full["seconds"].as_f64().unwrap_or(0.0)
    )));
    d
}
