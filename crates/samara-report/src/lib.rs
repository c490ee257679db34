//! Reports for samara: trajectory figures (PNG and SVG through `plotters`) and atomic
//! file output (write to a temporary file in the target directory, then rename, so an
//! interrupted run never leaves a half-written result).
#![warn(missing_docs)]

pub mod guard;
pub mod reach;

use plotters::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Errors writing a report file.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// I/O failure on a path.
    #[error("cannot write {path}: {source}; check that the directory exists and is writable")]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Drawing failed.
    #[error("cannot draw {path}: {message}")]
    Draw {
        /// The path.
        path: PathBuf,
        /// What plotters said.
        message: String,
    },
}

/// Write `bytes` to `path` atomically (temporary sibling + rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ReportError> {
    let io = |source| ReportError::Io {
        path: path.to_path_buf(),
        source,
    };
    let tmp = tmp_sibling(path);
    let res = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if res.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    res.map_err(io)
}

fn tmp_sibling(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// One curve of an x-y figure.
#[derive(Clone, Debug)]
pub struct Curve {
    /// Legend label.
    pub label: String,
    /// Points (x, y).
    pub points: Vec<(f64, f64)>,
}

/// An x-y trajectory figure: curves, the target line `y = -x`, equal axes, legend.
#[derive(Clone, Debug)]
pub struct TrajectoryFigure {
    /// Caption.
    pub title: String,
    /// Curves.
    pub curves: Vec<Curve>,
    /// Draw the band `|x + y| <= w` around the target line, if set.
    pub band: Option<f64>,
    /// Filled boxes (x_lo, x_hi, y_lo, y_hi) drawn under the curves (reachable sets).
    pub boxes: Vec<(f64, f64, f64, f64)>,
    /// Whether to draw a legend entry per curve (turn off for thousands of samples).
    pub legend: bool,
    /// With `legend` off: one legend entry for all curves together (e.g. "sampled
    /// trajectories"), if set.
    pub group_label: Option<String>,
}

impl TrajectoryFigure {
    /// A figure with the given title and curves.
    pub fn new(title: impl Into<String>, curves: Vec<Curve>) -> Self {
        TrajectoryFigure {
            title: title.into(),
            curves,
            band: None,
            boxes: Vec::new(),
            legend: true,
            group_label: None,
        }
    }

    /// Render to PNG and SVG (paths given), both atomically.
    pub fn render(&self, png: &Path, svg: &Path) -> Result<(), ReportError> {
        let tmp_png = tmp_sibling(png).with_extension("png");
        let tmp_svg = tmp_sibling(svg).with_extension("svg");
        let r = self
            .draw(
                BitMapBackend::new(&tmp_png, (1000, 1000)).into_drawing_area(),
                &tmp_png,
            )
            .and_then(|_| {
                self.draw(
                    SVGBackend::new(&tmp_svg, (1000, 1000)).into_drawing_area(),
                    &tmp_svg,
                )
            })
            .and_then(|_| {
                std::fs::rename(&tmp_png, png).map_err(|source| ReportError::Io {
                    path: png.into(),
                    source,
                })?;
                std::fs::rename(&tmp_svg, svg).map_err(|source| ReportError::Io {
                    path: svg.into(),
                    source,
                })
            });
        if r.is_err() {
            let _ = std::fs::remove_file(&tmp_png);
            let _ = std::fs::remove_file(&tmp_svg);
        }
        r
    }

    fn bounds(&self) -> (f64, f64, f64, f64) {
        let mut xs = (f64::INFINITY, f64::NEG_INFINITY);
        let mut ys = (f64::INFINITY, f64::NEG_INFINITY);
        let pts = self.curves.iter().flat_map(|c| c.points.iter().copied());
        let box_pts = self.boxes.iter().flat_map(|b| [(b.0, b.2), (b.1, b.3)]);
        for (x, y) in pts.chain(box_pts) {
            if x.is_finite() && y.is_finite() {
                xs = (xs.0.min(x), xs.1.max(x));
                ys = (ys.0.min(y), ys.1.max(y));
            }
        }
        if !xs.0.is_finite() {
            return (-1.0, 1.0, -1.0, 1.0);
        }
        // Equal axes: same span on both, centred on the data.
        let span = (xs.1 - xs.0).max(ys.1 - ys.0).max(1e-9) * 1.08;
        let cx = 0.5 * (xs.0 + xs.1);
        let cy = 0.5 * (ys.0 + ys.1);
        (
            cx - span / 2.0,
            cx + span / 2.0,
            cy - span / 2.0,
            cy + span / 2.0,
        )
    }

    fn draw<DB: DrawingBackend>(
        &self,
        area: DrawingArea<DB, plotters::coord::Shift>,
        path: &Path,
    ) -> Result<(), ReportError>
    where
        DB::ErrorType: 'static,
    {
        let err = |e: &dyn std::fmt::Display| ReportError::Draw {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        area.fill(&WHITE).map_err(|e| err(&e))?;
        let (x0, x1, y0, y1) = self.bounds();
        let mut chart = ChartBuilder::on(&area)
            .caption(&self.title, ("sans-serif", 26))
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("x (chords)")
            .y_desc("y (chords)")
            .label_style(("sans-serif", 18))
            .axis_desc_style(("sans-serif", 20))
            .draw()
            .map_err(|e| err(&e))?;
        if let Some(w) = self.band {
            let big = 4.0 * (x1 - x0 + y1 - y0).abs() + 1.0;
            let (a, b) = (x0 - big, x1 + big);
            let poly = clip_polygon(
                &[(a, -a + w), (b, -b + w), (b, -b - w), (a, -a - w)],
                (x0, x1, y0, y1),
            );
            chart
                .draw_series(std::iter::once(Polygon::new(
                    poly,
                    RGBColor(120, 200, 120).mix(0.25),
                )))
                .map_err(|e| err(&e))?
                .label(format!("band |x + y| <= {w}"))
                .legend(|(x, y)| {
                    Rectangle::new(
                        [(x, y - 5), (x + 20, y + 5)],
                        RGBColor(120, 200, 120).mix(0.4).filled(),
                    )
                });
        }
        if !self.boxes.is_empty() {
            // Outlined as well as filled, so thin (or degenerate) sets stay visible.
            chart
                .draw_series(self.boxes.iter().map(|b| {
                    Rectangle::new(
                        [(b.0, b.2), (b.1, b.3)],
                        RGBColor(90, 120, 220).mix(0.8).stroke_width(2),
                    )
                }))
                .map_err(|e| err(&e))?;
            chart
                .draw_series(self.boxes.iter().map(|b| {
                    Rectangle::new(
                        [(b.0, b.2), (b.1, b.3)],
                        RGBColor(90, 120, 220).mix(0.35).filled(),
                    )
                }))
                .map_err(|e| err(&e))?
                .label("reachable set")
                .legend(|(x, y)| {
                    Rectangle::new(
                        [(x, y - 5), (x + 20, y + 5)],
                        RGBColor(90, 120, 220).mix(0.5).filled(),
                    )
                });
        }
        chart
            .draw_series(LineSeries::new(
                vec![(x0.max(-y1), -x0.max(-y1)), (x1.min(-y0), -x1.min(-y0))],
                BLACK.stroke_width(2),
            ))
            .map_err(|e| err(&e))?
            .label("target y = -x")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
        let n = self.curves.len().max(1);
        for (i, c) in self.curves.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let color = if self.legend {
                color
            } else {
                RGBAColor(200, 60, 40, 0.35)
            };
            let _ = n;
            let s = chart
                .draw_series(LineSeries::new(
                    c.points.iter().copied(),
                    color.stroke_width(2),
                ))
                .map_err(|e| err(&e))?;
            let label = if self.legend {
                Some(c.label.clone())
            } else if i == 0 {
                self.group_label.clone()
            } else {
                None
            };
            if let Some(label) = label {
                s.label(label).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 16))
            .draw()
            .map_err(|e| err(&e))?;
        area.present().map_err(|e| err(&e))?;
        Ok(())
    }
}

/// Clip a convex polygon to the box `(x0, x1, y0, y1)` (Sutherland-Hodgman), so
/// plotters does not distort shapes that leave the chart area.
pub fn clip_polygon(poly: &[(f64, f64)], bx: (f64, f64, f64, f64)) -> Vec<(f64, f64)> {
    let (x0, x1, y0, y1) = bx;
    // Each edge: inside test and intersection.
    type Inside = fn(&(f64, f64), f64) -> bool;
    let edges: [(Inside, f64, bool); 4] = [
        (|p, c| p.0 >= c, x0, true),
        (|p, c| p.0 <= c, x1, true),
        (|p, c| p.1 >= c, y0, false),
        (|p, c| p.1 <= c, y1, false),
    ];
    let mut out = poly.to_vec();
    for (inside, c, vertical) in edges {
        let input = std::mem::take(&mut out);
        if input.is_empty() {
            break;
        }
        for i in 0..input.len() {
            let p = input[i];
            let q = input[(i + 1) % input.len()];
            let cross = |p: (f64, f64), q: (f64, f64)| {
                if vertical {
                    let t = (c - p.0) / (q.0 - p.0);
                    (c, p.1 + t * (q.1 - p.1))
                } else {
                    let t = (c - p.1) / (q.1 - p.1);
                    (p.0 + t * (q.0 - p.0), c)
                }
            };
            match (inside(&p, c), inside(&q, c)) {
                (true, true) => out.push(q),
                (true, false) => out.push(cross(p, q)),
                (false, true) => {
                    out.push(cross(p, q));
                    out.push(q);
                }
                (false, false) => {}
            }
        }
    }
    out
}

/// Format a float so it parses back to the same value (shortest round-trip form).
pub fn fmt_f64(v: f64) -> String {
    format!("{v:?}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_write_replaces_and_leaves_no_temp() {
        let dir = std::env::temp_dir().join(format!("samara-report-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("a.txt");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "two");
        let entries: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(entries.len(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn figure_renders_png_and_svg() {
        let dir = std::env::temp_dir().join(format!("samara-fig-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let c = Curve {
            label: "y0 = 1".into(),
            points: (0..50).map(|i| (i as f64, 1.0 - i as f64 * 0.9)).collect(),
        };
        let mut fig = TrajectoryFigure::new("test", vec![c]);
        fig.band = Some(2.0);
        fig.render(&dir.join("t.png"), &dir.join("t.svg")).unwrap();
        assert!(std::fs::metadata(dir.join("t.png")).unwrap().len() > 1000);
        let svg = std::fs::read_to_string(dir.join("t.svg")).unwrap();
        assert!(svg.contains("<svg") && svg.contains("target y = -x"));
        // One legend entry for a group of unlabelled curves.
        fig.legend = false;
        fig.group_label = Some("sampled trajectories".into());
        fig.boxes = vec![(0.0, 1.0, 0.0, 1.0)];
        fig.render(&dir.join("t.png"), &dir.join("t.svg")).unwrap();
        let svg = std::fs::read_to_string(dir.join("t.svg")).unwrap();
        assert!(svg.contains("sampled trajectories") && !svg.contains("y0 = 1"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
