//! `samara reproduce`: the whole Alsomitra case study in one command, from nothing but
//! the repository. Each stage writes its files atomically and records its result in a
//! cache keyed by its inputs, so an interrupted run leaves no half-written report and a
//! re-run reuses what is finished. The report (`report.md`, `report.html`) and
//! `results.json` are written last.
//!
//! P1-P4 come from a specification ([`ReproSpec`]): the shipped
//! `models/alsomitra/alsomitra.spec` by default, or any edited copy (`samara reproduce
//! --spec FILE`). The stages take it from [`Ctx::spec`] (training's DL2/Goedel
//! constraints, the critical values of the verify stage, the units and domain of the
//! networks), and its text is part of every stage's cache key, so an edited spec is never
//! served from a stage cached under another.
#![warn(missing_docs)]

pub mod cache;
mod common;
pub mod doc;
mod flights_stage;
mod reach_stage;
pub mod results;
mod sections;
mod spec_check;
#[cfg(test)]
mod stage_tests;
pub mod stages;
mod train_stage;
mod verify_stage;

use cache::Cache;
use doc::{Block, Document};
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use results::{Results, SpecDigest, Stages};
use samara_spec::Spec;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The specification a reproduction lowers P1-P4 from, checked for what the stages
/// lower; its text ([`Spec::source`]) is hashed into the stage cache keys and
/// `results.json`.
#[derive(Clone, Debug)]
pub struct ReproSpec {
    spec: Spec,
}

impl ReproSpec {
    /// The shipped case-study spec, `models/alsomitra/alsomitra.spec` (compiled in).
    pub fn shipped() -> Self {
        ReproSpec {
            spec: samara_train::case_study_spec(),
        }
    }

    /// Read, parse and check a spec file (messages carry `file:line:col`), and check that
    /// it states what the stages lower (see [`ReproSpec::parse`]).
    pub fn read(path: &Path) -> Result<Self, ReproError> {
        Self::checked(Spec::read(path).map_err(ReproError::spec)?)
    }

    /// Parse and check spec text (`file` names it in messages, `dir` resolves its data
    /// paths). The stages need a first network with the six state inputs and one output
    /// and properties `p1`-`p4` that lower both as critical-value queries over `ystar`
    /// (verify stage) and as training properties with `ystar` at its default (DL2 and
    /// Goedel training); anything else is refused here, before any stage runs.
    pub fn parse(text: &str, file: &str, dir: &Path) -> Result<Self, ReproError> {
        Self::checked(Spec::parse(text, file, dir).map_err(ReproError::spec)?)
    }

    fn checked(spec: Spec) -> Result<Self, ReproError> {
        spec_check::check_spec(&spec).map_err(|message| ReproError::Spec { message })?;
        Ok(ReproSpec { spec })
    }

    /// The checked spec.
    pub fn spec(&self) -> &Spec {
        &self.spec
    }

    /// The spec's text, as read.
    pub fn text(&self) -> &str {
        self.spec.source()
    }

    /// The spec's file name, as given.
    pub fn file(&self) -> &str {
        &self.spec.file
    }
}

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
    /// The specification P1-P4 are lowered from ([`ReproSpec::shipped`] for the case
    /// study as published).
    pub spec: ReproSpec,
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
    /// The specification cannot be read, does not parse or check, or does not state
    /// what the stages lower (the message carries `file:line:col` where it has one).
    #[error("{message}")]
    Spec {
        /// The spec error, with its place and fix.
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

impl ReproError {
    fn spec(e: samara_spec::SpecError) -> Self {
        ReproError::Spec {
            message: e.to_string().trim_end().to_string(),
        }
    }
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

    /// The specification of the run (P1-P4, the network's units and domain).
    pub fn spec(&self) -> &Spec {
        self.opts.spec.spec()
    }

    /// Absolute path of an output file.
    pub fn path(&self, rel: &str) -> PathBuf {
        self.opts.out.join(rel)
    }
}

/// Outcome of a run.
#[derive(Debug)]
pub struct Outcome {
    /// Every number of the run (`results.json`).
    pub results: Results,
    /// Stages taken from the cache.
    pub reused: Vec<String>,
    /// Wall time.
    pub seconds: f64,
}

/// A stage: reads the results of the stages before it, stores its own in the
/// [`Stages`] it is given, and returns the files it wrote (relative to the output
/// directory).
type StageFn = fn(&Ctx, &mut Stages) -> Result<Vec<String>, ReproError>;

fn mode(opts: &ReproduceOptions) -> &'static str {
    if opts.quick {
        "quick"
    } else {
        "full"
    }
}

/// The cache key of `stage`: everything its result depends on (the samara version, the
/// mode, the published folder, the spec's text) and the key of the stage before it.
/// The spec enters as its text, not its path: the stages read no file the spec names,
/// so the same text gives the same results wherever it lies, and any edit of it (even
/// a comment) recomputes every stage.
fn stage_key(opts: &ReproduceOptions, stage: &str, prev: &str) -> String {
    let published = opts
        .published
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    cache::fnv1a(&[
        stage,
        env!("CARGO_PKG_VERSION"),
        mode(opts),
        &published,
        opts.spec.text(),
        prev,
    ])
}

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
    let mode = mode(opts);

    let mut results = Stages::default();
    let mut reused = Vec::new();
    let mut prev_key = String::new();
    let all = stages::all();
    let overall = ctx.bar(all.len() as u64, "reproduce");
    for (name, f) in all {
        overall.set_message(format!("stage {name}"));
        let key = stage_key(opts, name, &prev_key);
        // A cached entry that no longer has its stage's shape is recomputed.
        let cached = cache
            .get(name, &key, &opts.out)
            .is_some_and(|r| results.restore(name, r));
        if cached {
            reused.push(name.to_string());
        } else {
            let files = f(&ctx, &mut results)?;
            cache
                .put(name, &key, &files, &results.entry_json(name))
                .map_err(|e| io(&opts.out.join(".cache"), &e))?;
        }
        prev_key = key;
        overall.inc(1);
    }
    overall.finish_and_clear();
    let seconds = t0.elapsed().as_secs_f64();
    let full = Results {
        command_line: opts.command_line.clone(),
        mode: mode.to_string(),
        samara_version: version.to_string(),
        seconds,
        spec: SpecDigest {
            file: opts.spec.file().to_string(),
            fnv1a: cache::fnv1a(&[opts.spec.text()]),
        },
        stages: results,
    };
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
pub fn new_report(full: &Results) -> Document {
    let mut d = Document::new("samara: the Alsomitra case study, reproduced");
    d.push(Block::Para(format!(
        "Produced by `{}` (samara {}, {} mode) in {:.1} s, P1-P4 as `{}` states them. Every number below is computed by this run; `results.json` holds them all.",
        full.command_line, full.samara_version, full.mode, full.seconds, full.spec.file
    )));
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(spec: ReproSpec) -> ReproduceOptions {
        ReproduceOptions {
            out: PathBuf::from("out"),
            quick: true,
            published: None,
            fresh: false,
            progress: false,
            command_line: String::new(),
            spec,
        }
    }

    #[test]
    fn an_edited_spec_is_never_served_from_the_cache() {
        let shipped = opts(ReproSpec::shipped());
        // The shipped spec keeps the keys of the runs before --spec existed.
        let key = stage_key(&shipped, "data", "");
        let version = env!("CARGO_PKG_VERSION");
        let before = cache::fnv1a(&[
            "data",
            version,
            "quick",
            "",
            samara_train::CASE_STUDY_SPEC,
            "",
        ]);
        assert_eq!(key, before);
        // The same text read from a file elsewhere: the same key.
        let elsewhere = ReproSpec::parse(
            samara_train::CASE_STUDY_SPEC,
            "copy.spec",
            Path::new("/tmp"),
        )
        .unwrap();
        assert_eq!(stage_key(&opts(elsewhere), "data", ""), key);
        // Any edit: another key for every stage.
        let text = samara_train::CASE_STUDY_SPEC.replace("=> ex >= 0.187", "=> ex >= 0.2");
        let edited = opts(ReproSpec::parse(&text, "e.spec", Path::new(".")).unwrap());
        for stage in ["data", "train", "verify"] {
            assert_ne!(
                stage_key(&edited, stage, ""),
                stage_key(&shipped, stage, "")
            );
        }
    }
}
