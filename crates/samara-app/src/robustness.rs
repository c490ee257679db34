//! The robustness table of a sweep (`samara robustness`, `samara.robustness`).

use samara_verify::robustness::{lipschitz_cell, published_cell, PointBall};
use serde::{Deserialize, Serialize};

/// The form of the robustness property.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Form {
    /// `|f(x') - ref| <= L / eps` (the published P5).
    Published,
    /// `|f(x') - f(x)| <= L ||x' - x||`.
    Lipschitz,
}

impl Form {
    /// The form named `s` (`published`, `lipschitz`).
    pub fn parse(s: &str) -> Option<Form> {
        match s {
            "published" => Some(Form::Published),
            "lipschitz" => Some(Form::Lipschitz),
            _ => None,
        }
    }

    /// Its name.
    pub fn text(self) -> &'static str {
        match self {
            Form::Published => "published",
            Form::Lipschitz => "lipschitz",
        }
    }
}

/// One cell of the table: the data points at radius `eps` and bound `L`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Cell {
    /// The radius.
    pub eps: f64,
    /// The bound.
    #[serde(rename = "L")]
    pub l: f64,
    /// Points proved robust.
    pub proved: usize,
    /// Points with a concrete violation.
    pub violated: usize,
    /// Points neither (their search was cut short).
    pub unknown: usize,
    /// `proved` over the number of data points.
    pub success_rate: f64,
}

/// The table: one row per radius, one cell per bound.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Table {
    /// The form.
    pub form: Form,
    /// How many data points.
    pub points: usize,
    /// Wall time of the sweep.
    pub seconds: f64,
    /// Rows by radius, cells by bound.
    pub table: Vec<Vec<Cell>>,
}

impl Table {
    /// The table of a sweep's `points` over `n_rows` data points.
    pub fn of(
        form: Form,
        eps: &[f64],
        ls: &[f64],
        n_rows: usize,
        seconds: f64,
        points: &[PointBall],
    ) -> Table {
        let table = eps
            .iter()
            .map(|e| {
                ls.iter()
                    .map(|l| {
                        let c = match form {
                            Form::Published => published_cell(points, *e, *l),
                            Form::Lipschitz => lipschitz_cell(points, *e, *l),
                        };
                        Cell {
                            eps: *e,
                            l: *l,
                            proved: c.proved,
                            violated: c.violated,
                            unknown: c.unknown,
                            success_rate: c.proved as f64 / n_rows.max(1) as f64,
                        }
                    })
                    .collect()
            })
            .collect();
        Table {
            form,
            points: n_rows,
            seconds,
            table,
        }
    }

    /// Some cell has unknown points.
    pub fn any_unknown(&self) -> bool {
        self.table.iter().flatten().any(|c| c.unknown > 0)
    }
}
