//! `samara export-vnnlib`: every instance of the selected properties written as a
//! VNN-LIB 1.0 file (relational instances over the stacked network, written as ONNX
//! beside them).

use crate::args::ExportArgs;
use crate::bind::Loaded;
use anyhow::{anyhow, bail, Result};
use samara_spec::vnnlib;
use std::path::Path;

/// What an export wrote and what it could not write.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Exported {
    /// Number of `.vnnlib` files written.
    pub written: usize,
    /// The instances or properties not written, each with why.
    pub skipped: Vec<String>,
}

impl Exported {
    /// The report on stderr after a run that wrote something: the count, then at most
    /// ten skipped instances and the error line when any was skipped (exit 1).
    pub fn lines(&self, out: &Path) -> Vec<String> {
        let mut v = vec![format!(
            "wrote {} VNN-LIB file(s) to {}",
            self.written,
            out.display()
        )];
        if !self.skipped.is_empty() {
            v.extend(self.skipped.iter().take(10).map(|m| format!("skipped {m}")));
            if self.skipped.len() > 10 {
                v.push(format!("... and {} more", self.skipped.len() - 10));
            }
            v.push(format!(
                "error: {} instance(s) or propert(ies) were NOT written (see above); select properties with --property",
                self.skipped.len()
            ));
        }
        v
    }
}

/// Write the instances of `a.property` (or of every property) of the loaded spec into
/// the new or empty folder `a.out`. When nothing could be written the folder is removed
/// again and `written` is 0.
pub fn export_vnnlib(l: &Loaded, a: &ExportArgs) -> Result<Exported> {
    if let Some(p) = &a.property {
        if !l.spec.property_names().contains(&p.as_str()) {
            bail!(
                "--property {p}: the spec {} declares no property `{p}`; {}",
                a.s.spec.display(),
                crate::suggest(p, l.spec.property_names())
            );
        }
    }
    let names = l.selected(a.property.as_deref());
    // Output protection: never into (or over) an input, never mixed with old files.
    let mut inputs: Vec<(&str, &Path)> = vec![("the spec", a.s.spec.as_path())];
    for f in &l.net_files {
        inputs.push(("--network", f.as_path()));
    }
    for f in l.b.datasets.values() {
        inputs.push(("--dataset", f.as_path()));
    }
    samara_report::guard::check_output_dir("--out", &a.out, &[], &inputs)?;
    if a.out.is_dir() {
        let used = std::fs::read_dir(&a.out)
            .map_err(|e| anyhow!("--out {}: {e}", a.out.display()))?
            .next()
            .is_some();
        if used {
            bail!(
                "--out {}: the folder is not empty; export-vnnlib writes only into an empty or new folder (old and new .vnnlib files would mix): choose a new --out or empty it",
                a.out.display()
            );
        }
    }
    let dir = samara_report::guard::OutDir::prepare(&a.out)?;
    let mut done = Exported::default();
    for name in &names {
        if let Some(m) = l.missing_data(name) {
            done.skipped.push(m);
            continue;
        }
        let inst = match l.spec.lower_prove(name, &l.b) {
            Ok(i) => i,
            Err(e) => {
                done.skipped
                    .push(format!("property {name}: {} ({})", e.message, e.hint));
                continue;
            }
        };
        for i in inst {
            // Relational instances: rewrite over the stacked network and write its ONNX.
            let mut q = i.query.clone();
            if q.applications.len() > 1 {
                let Some((sq, k)) = vnnlib::stack_applications(&q) else {
                    done.skipped
                        .push(format!("{}: it calls different networks", i.label));
                    continue;
                };
                let base = &i.query.applications[0].network;
                let Some(net) = l.nets.get(base) else {
                    done.skipped.push(format!("{}: relational; pass --network {base}=FILE to write the {k}-fold stacked ONNX it needs", i.label));
                    continue;
                };
                let onnx_path = a.out.join(format!("{}.onnx", sq.applications[0].network));
                if !onnx_path.exists() {
                    samara_nn::onnx::save(&net.stacked(k), &onnx_path, &Default::default())
                        .map_err(|e| anyhow!("--out: writing {}: {e}", onnx_path.display()))?;
                }
                q = sq;
            }
            let parts = if a.split_disjuncts {
                vnnlib::split_disjuncts(&q)
            } else {
                vec![q]
            };
            for part in parts {
                match vnnlib::export(&part) {
                    Ok(text) => {
                        let file = a
                            .out
                            .join(format!("{}.vnnlib", part.name.replace(['[', ']'], "_")));
                        samara_report::write_atomic(&file, text.as_bytes())
                            .map_err(|e| anyhow!("--out: writing {}: {e}", file.display()))?;
                        done.written += 1;
                    }
                    Err(e) => done.skipped.push(e.to_string()),
                }
            }
        }
    }
    if done.written > 0 {
        dir.keep();
    }
    Ok(done)
}
