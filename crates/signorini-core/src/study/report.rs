//! A study's results: one point per run (error, CPU time), the observed orders, `study.csv`,
//! the work–precision chart and `summary.json`.

use super::Study;
use crate::outcome::{Chart, Table, WorkPrecisionChart, WorkPrecisionCurve};
use crate::spec::study::ErrorNorm;
use serde::Serialize;
use serde_json::Value;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// The result of one run of a study.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyPoint {
    /// Which of `study.schemes`.
    pub scheme_index: usize,
    /// The scheme's label.
    pub label: String,
    /// The grid values of the run, per axis.
    pub values: Vec<Value>,
    /// Step size.
    pub h: f64,
    /// Steps taken.
    pub steps: u64,
    /// CPU seconds of the run (measured by the caller).
    pub cpu_s: f64,
    /// Error against the reference, in the study's norm.
    pub error: f64,
    /// Largest |balance_residual| (NaN when the scheme reports none).
    pub max_balance_residual: f64,
    /// Largest |energy_error| (NaN when the scheme reports none).
    pub max_energy_error: f64,
}

impl StudyPoint {
    /// The point of `run`: its steps, CPU seconds and error, and the energy checks of its
    /// `samples` (NaN without samples: a run that failed).
    pub fn new(
        run: &super::StudyRun,
        steps: u64,
        cpu_s: f64,
        error: f64,
        samples: Option<&super::Samples>,
    ) -> Self {
        StudyPoint {
            scheme_index: run.scheme_index,
            label: run.label.clone(),
            values: run.values.clone(),
            h: run.h,
            steps,
            cpu_s,
            error,
            max_balance_residual: samples.map_or(f64::NAN, |s| s.max_balance_residual),
            max_energy_error: samples.map_or(f64::NAN, |s| s.max_energy_error),
        }
    }
}

/// The observed order of convergence of one scheme (at fixed values of the other grid axes):
/// the least-squares slope of log(error) against log(h).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObservedOrder {
    /// The scheme's label.
    pub scheme: String,
    /// The values of the grid axes other than `time.h`.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub at: BTreeMap<String, Value>,
    /// The slope.
    pub order: f64,
    /// How many runs (distinct h, error > 0) the slope is fitted on.
    pub points: usize,
}

/// `summary.json` of a study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudySummary {
    /// `"study"`.
    pub kind: &'static str,
    /// The base spec's name.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The base model's scene.
    pub scene: String,
    /// What the runs are compared with.
    pub reference: String,
    /// The error norm.
    pub error: &'static str,
    /// Number of runs.
    pub runs: usize,
    /// The scheme labels, in `study.schemes` order.
    pub schemes: Vec<String>,
    /// The grid's field paths.
    pub axes: Vec<String>,
    /// Observed orders (empty without a `time.h` axis).
    pub orders: Vec<ObservedOrder>,
    /// Sum of the runs' CPU seconds.
    pub cpu_s_total: f64,
}

/// A study's points and what is made of them.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyReport {
    name: Option<String>,
    scene: String,
    reference: String,
    error: ErrorNorm,
    axes: Vec<String>,
    schemes: Vec<String>,
    /// One point per run, in the study's run order.
    pub points: Vec<StudyPoint>,
}

/// Least-squares slope of y against x.
fn slope(xy: &[(f64, f64)]) -> f64 {
    let n = xy.len() as f64;
    let (mx, my) = xy
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (sxy, sxx) = xy.iter().fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    sxy / sxx
}

impl StudyReport {
    /// The report of `study` with one point per run.
    pub fn new(study: &Study, points: Vec<StudyPoint>) -> Self {
        let mut schemes: Vec<String> = Vec::new();
        for r in &study.runs {
            if schemes.len() <= r.scheme_index {
                schemes.push(r.label.clone());
            }
        }
        Self {
            name: study.name.clone(),
            scene: study.scene.clone(),
            reference: study.reference.describe(&study.spec.reference),
            error: study.spec.error,
            axes: study.axes.clone(),
            schemes,
            points,
        }
    }

    /// Position of the `time.h` axis.
    fn h_axis(&self) -> Option<usize> {
        self.axes.iter().position(|a| super::is_step_axis(a))
    }

    /// Whether axis `i` takes more than one value in the study.
    fn varies(&self, i: usize) -> bool {
        let mut values = self.points.iter().map(|p| &p.values[i]);
        let first = values.next();
        values.any(|v| Some(v) != first)
    }

    /// The points grouped by scheme and by the values of the axes other than the step axis
    /// (axes with a single value are constants, not groups).
    fn groups(&self) -> Vec<(String, BTreeMap<String, Value>, Vec<&StudyPoint>)> {
        let h_axis = self.h_axis();
        let mut groups: Vec<(usize, BTreeMap<String, Value>, Vec<&StudyPoint>)> = Vec::new();
        for p in &self.points {
            let at: BTreeMap<String, Value> = self
                .axes
                .iter()
                .zip(&p.values)
                .enumerate()
                .filter(|(i, _)| Some(*i) != h_axis && self.varies(*i))
                .map(|(_, (a, v))| (a.clone(), v.clone()))
                .collect();
            match groups
                .iter_mut()
                .find(|(s, a, _)| *s == p.scheme_index && *a == at)
            {
                Some(g) => g.2.push(p),
                None => groups.push((p.scheme_index, at, vec![p])),
            }
        }
        groups
            .into_iter()
            .map(|(s, at, pts)| {
                let label = self.schemes.get(s).cloned().unwrap_or_default();
                (label, at, pts)
            })
            .collect()
    }

    /// The observed orders: per scheme and values of the other axes, the slope of log(error)
    /// against log(h) over the runs with a finite positive error (at least two distinct h).
    pub fn orders(&self) -> Vec<ObservedOrder> {
        if self.h_axis().is_none() {
            return Vec::new();
        }
        self.groups()
            .into_iter()
            .filter_map(|(scheme, at, pts)| {
                let xy: Vec<(f64, f64)> = pts
                    .iter()
                    .filter(|p| p.error.is_finite() && p.error > 0.0 && p.h > 0.0)
                    .map(|p| (p.h.ln(), p.error.ln()))
                    .collect();
                let distinct = xy.iter().any(|a| a.0 != xy[0].0);
                (xy.len() >= 2 && distinct).then(|| ObservedOrder {
                    scheme,
                    at,
                    order: slope(&xy),
                    points: xy.len(),
                })
            })
            .collect()
    }

    /// `study.csv`: one row per run — scheme, the grid values, h, steps, CPU seconds, error,
    /// largest |balance_residual| and |energy_error| (empty where the scheme reports none).
    pub fn csv(&self) -> String {
        let mut s = String::from("run,scheme");
        for a in &self.axes {
            let _ = write!(s, ",{a}");
        }
        s.push_str(",h,steps,cpu_s,error,max_balance_residual,max_energy_error\n");
        let num = |x: f64| {
            if x.is_nan() {
                String::new()
            } else {
                format!("{x:e}")
            }
        };
        for (i, p) in self.points.iter().enumerate() {
            let _ = write!(s, "{i},\"{}\"", p.label.replace('"', "\"\""));
            for v in &p.values {
                let _ = write!(s, ",{}", v.to_string().replace(',', ";"));
            }
            let _ = writeln!(
                s,
                ",{:e},{},{:e},{},{},{}",
                p.h,
                p.steps,
                p.cpu_s,
                num(p.error),
                num(p.max_balance_residual),
                num(p.max_energy_error)
            );
        }
        s
    }

    /// `study.csv` as a numeric [`Table`] named `study` (what the service stores as the
    /// parent job's table): `run`, `scheme` (the index into [`StudySummary::schemes`]), one
    /// column per grid field path (an axis of several paths gives one column each; a value that
    /// is not a number is NaN), then `h, steps, cpu_s, error, max_balance_residual,
    /// max_energy_error` as in [`StudyReport::csv`] (NaN where that is empty).
    pub fn table(&self) -> Table {
        let paths: Vec<Vec<&str>> = self
            .axes
            .iter()
            .map(|a| a.split(',').map(str::trim).collect())
            .collect();
        let mut columns = vec!["run".to_string(), "scheme".to_string()];
        columns.extend(paths.iter().flatten().map(|p| p.to_string()));
        columns.extend(
            [
                "h",
                "steps",
                "cpu_s",
                "error",
                "max_balance_residual",
                "max_energy_error",
            ]
            .map(String::from),
        );
        let number = |v: Option<&Value>| v.and_then(Value::as_f64).unwrap_or(f64::NAN);
        let rows = self
            .points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut row = vec![i as f64, p.scheme_index as f64];
                for (v, ps) in p.values.iter().zip(&paths) {
                    if ps.len() == 1 {
                        row.push(number(Some(v)));
                    } else {
                        row.extend((0..ps.len()).map(|k| number(v.get(k))));
                    }
                }
                row.extend([
                    p.h,
                    p.steps as f64,
                    p.cpu_s,
                    p.error,
                    p.max_balance_residual,
                    p.max_energy_error,
                ]);
                row
            })
            .collect();
        Table {
            name: "study".into(),
            columns,
            rows,
        }
    }

    /// `work_precision`: error against CPU seconds, log–log, a curve per scheme (and values of
    /// the other axes) with its observed order in the legend and each point's h, the reference
    /// and the norm in the title.
    pub fn chart(&self) -> Chart {
        let orders = self.orders();
        let curves = self
            .groups()
            .into_iter()
            .map(|(scheme, at, pts)| {
                let order = orders
                    .iter()
                    .find(|o| o.scheme == scheme && o.at == at)
                    .map(|o| o.order);
                let mut label = scheme;
                if !at.is_empty() {
                    let parts: Vec<String> = at.iter().map(|(a, v)| format!("{a}={v}")).collect();
                    let _ = write!(label, " [{}]", parts.join(", "));
                }
                if let Some(order) = order {
                    let _ = write!(label, ", observed order {order:.2}");
                }
                let mut runs: Vec<(f64, f64, f64)> =
                    pts.iter().map(|p| (p.cpu_s, p.error, p.h)).collect();
                runs.sort_by(|a, b| a.0.total_cmp(&b.0));
                WorkPrecisionCurve {
                    label,
                    points: runs.iter().map(|r| (r.0, r.1)).collect(),
                    h: runs.iter().map(|r| r.2).collect(),
                }
            })
            .collect();
        Chart::WorkPrecision(WorkPrecisionChart {
            title: format!(
                "{}: {} error against {}",
                self.name.as_deref().unwrap_or(&self.scene),
                self.error.name(),
                self.reference
            ),
            curves,
        })
    }

    /// `summary.json`.
    pub fn summary(&self) -> StudySummary {
        StudySummary {
            kind: "study",
            name: self.name.clone(),
            scene: self.scene.clone(),
            reference: self.reference.clone(),
            error: self.error.name(),
            runs: self.points.len(),
            schemes: self.schemes.clone(),
            axes: self.axes.clone(),
            orders: self.orders(),
            cpu_s_total: self.points.iter().map(|p| p.cpu_s).sum(),
        }
    }
}
