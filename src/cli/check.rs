//! `signorini check SPEC… [--junit FILE]`: the CI gate. Runs each spec in this process and
//! checks the bounds of its `[check]` section against what the run measured; one line per
//! bound. Exit 0 when every bound holds, 1 when a bound fails or a run fails, 2 on a bad spec
//! (unreadable, invalid, or a bound its run cannot measure).

use crate::spec_file::{self, Format};
use anyhow::{Context, Result};
use clap::Args;
use quick_junit::{NonSuccessKind, Report, TestCase, TestCaseStatus, TestSuite};
use serde_json::{Map, Value};
use signorini_core::job::{self, Job};
use signorini_core::observer::{Columns, Observer, StepRecord};
use signorini_core::spec::JobSpec;
use signorini_core::spec::check::CheckSpec;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Arguments of `signorini check`.
#[derive(Debug, Args)]
#[command(after_help = "\
Each spec's [check] section gives bounds (all optional):
  max_balance_residual  largest |balance_residual| (linear schemes' energy identity)
  max_energy_error      largest |energy_error| (nonlinear and SOI2 schemes)
  max_energy_growth     largest (E - E0 - works) / max(|E0|, max|E|) (energy created)
  max_error             largest global error against the scene's exact solution
  min_order             smallest observed order (studies only)
  max_position_residual largest position_residual (joints, SOI2 schemes)
  [[check.reference]]   { column, t, value, tolerance }: |column(t) - value| <= tolerance
A spec without [check] passes when its run succeeds.

Exit status: 0 every bound holds, 1 a bound or a run failed, 2 a bad spec.

  signorini check examples/*.toml --junit check.xml")]
pub struct CheckArgs {
    /// Job spec files (TOML, or JSON when the name ends in .json).
    #[arg(required = true)]
    pub specs: Vec<PathBuf>,
    /// Also write the verdicts as JUnit XML (one test suite, one test case per bound).
    #[arg(long)]
    pub junit: Option<PathBuf>,
}

/// How `signorini check` ends: the exit status main returns, after the lines are printed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("check exit status {0}")]
pub struct CheckExit(pub u8);

/// One verdict line.
struct Line {
    spec: String,
    bound: String,
    outcome: Outcome,
    time: Duration,
}

enum Outcome {
    /// A bound and its measured value: holds or not.
    Measured {
        value: f64,
        limit: f64,
        holds: bool,
        relation: &'static str,
    },
    /// The run ran and no bound was given.
    RunSucceeded,
    /// The run failed.
    RunFailed(String),
    /// The spec is bad: unreadable, invalid, or a bound its run cannot measure.
    BadSpec(String),
}

/// The maxima over the recorded steps that the bounds compare with.
#[derive(Default)]
struct Measured {
    balance: Option<usize>,
    energy_error: Option<usize>,
    energy: Option<usize>,
    works: Vec<usize>,
    max_balance: f64,
    max_energy_error: f64,
    energy_initial: Option<f64>,
    energy_scale: f64,
    max_growth: f64,
    position: Option<usize>,
    max_position: f64,
    /// Per `[[check.reference]]`: the column's index, and the recorded (|t − t_ref|, value)
    /// nearest to the reference instant so far.
    references: Vec<(Option<usize>, Option<Nearest>)>,
    reference_times: Vec<(String, f64)>,
}

/// A recorded value nearest to a reference instant: (|t − t_ref|, value).
type Nearest = (f64, f64);

impl Observer for Measured {
    fn start(&mut self, columns: &Columns) {
        let names = columns.names();
        let find = |n: &str| names.iter().position(|c| c == n);
        self.balance = find("balance_residual");
        self.energy_error = find("energy_error");
        self.energy = find("energy");
        self.works = names
            .iter()
            .enumerate()
            .filter(|(_, c)| c.starts_with("work_") && c.ends_with("_total"))
            .map(|(i, _)| i)
            .collect();
        self.max_growth = f64::NEG_INFINITY;
        self.position = find("position_residual");
        self.references = self
            .reference_times
            .iter()
            .map(|(c, _)| (find(c), None))
            .collect();
    }

    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        let v = record.values;
        if let Some(i) = self.balance {
            self.max_balance = self.max_balance.max(v[i].abs());
        }
        if let Some(i) = self.energy_error {
            self.max_energy_error = self.max_energy_error.max(v[i].abs());
        }
        if let Some(e) = self.energy.map(|i| v[i]) {
            let e0 = *self.energy_initial.get_or_insert(e);
            self.energy_scale = self.energy_scale.max(e0.abs()).max(e.abs());
            // E − E₀ − works: the scheme's own energy_error where it reports one.
            let growth = match self.energy_error {
                Some(i) => v[i],
                None => e - e0 - self.works.iter().map(|&w| v[w]).sum::<f64>(),
            };
            self.max_growth = self.max_growth.max(growth);
        }
        if let Some(i) = self.position {
            self.max_position = self.max_position.max(v[i].abs());
        }
        for ((column, best), (_, t)) in self.references.iter_mut().zip(&self.reference_times) {
            let distance = (record.t - t).abs();
            if let Some(i) = column
                && best.is_none_or(|(d, _)| distance < d)
            {
                *best = Some((distance, v[*i]));
            }
        }
        ControlFlow::Continue(())
    }
}

impl Measured {
    /// The measured value a bound compares with, or why the run cannot measure it.
    fn value(&self, bound: &str, summary: &Map<String, Value>) -> Result<f64, String> {
        match bound {
            "max_balance_residual" => match self.balance {
                Some(_) => Ok(self.max_balance),
                None => Err("this run reports no balance_residual (nonlinear and SOI2 schemes report energy_error)".into()),
            },
            "max_energy_error" => match self.energy_error {
                Some(_) => Ok(self.max_energy_error),
                None => Err("this run reports no energy_error (the linear schemes report balance_residual)".into()),
            },
            "max_energy_growth" => match self.energy_initial {
                Some(_) => Ok(self.max_growth / self.energy_scale.max(f64::MIN_POSITIVE)),
                None => Err("this run records no energy column".into()),
            },
            "max_error" => match summary.get("errors") {
                Some(Value::Object(errors)) => Ok(errors
                    .values()
                    .filter_map(Value::as_f64)
                    .fold(0.0, f64::max)),
                _ => Err("this scene has no exact solution to measure an error against".into()),
            },
            "max_position_residual" => match self.position {
                Some(_) => Ok(self.max_position),
                None => Err("this run reports no position_residual (no joints)".into()),
            },
            other => Err(format!("{other} is not measured by a single run")),
        }
    }
}

/// Runs one spec and returns its verdict lines.
fn check_one(path: &Path) -> Vec<Line> {
    let name = path.display().to_string();
    let bad = |reason: String| {
        vec![Line {
            spec: name.clone(),
            bound: "spec".into(),
            outcome: Outcome::BadSpec(reason),
            time: Duration::ZERO,
        }]
    };
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) => return bad(format!("reading: {e}")),
    };
    let spec = match spec_file::parse(&text, Format::of_path(path)) {
        Ok(s) => s,
        Err(e) => return bad(e.to_string()),
    };
    if spec.study.is_some() {
        return check_study(path, &spec);
    }
    let job: Job = match spec_file::load(&text, Format::of_path(path)) {
        Ok(j) => j,
        Err(e) => return bad(e.to_string()),
    };
    let check: CheckSpec = job.spec().check.clone().unwrap_or_default();
    let mut measured = Measured {
        reference_times: check
            .reference
            .iter()
            .map(|r| (r.column.clone(), r.t))
            .collect(),
        ..Measured::default()
    };
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let started = Instant::now();
    let result = job::run_with_detectors(
        &job,
        threads,
        &mut measured,
        None,
        &signorini_collision::ParryDetectors,
    );
    let time = started.elapsed();
    let output = match result {
        Ok(o) => o,
        Err(e) => {
            return vec![Line {
                spec: name,
                bound: "run".into(),
                outcome: Outcome::RunFailed(e.to_string()),
                time,
            }];
        }
    };
    // Only the summary is read: the figures a run's charts make are not drawn here.
    let summary = output.summary.with_timing(time).to_map();
    let bounds = check.bounds();
    if bounds.is_empty() && check.reference.is_empty() {
        return vec![Line {
            spec: name,
            bound: "run".into(),
            outcome: Outcome::RunSucceeded,
            time,
        }];
    }
    let references = check
        .reference
        .iter()
        .zip(&measured.references)
        .map(|(r, got)| {
            let bound = format!("reference {} at t = {}", r.column, r.t);
            let outcome = match got {
                (None, _) => Outcome::BadSpec(format!(
                    "check.reference: this run records no column `{}`",
                    r.column
                )),
                (Some(_), None) => Outcome::BadSpec("check.reference: no step was recorded".into()),
                (Some(_), Some((_, value))) => {
                    let error = (value - r.value).abs();
                    Outcome::Measured {
                        value: error,
                        limit: r.tolerance,
                        holds: error <= r.tolerance,
                        relation: "≤",
                    }
                }
            };
            Line {
                spec: name.clone(),
                bound,
                outcome,
                time,
            }
        });
    let references: Vec<Line> = references.collect();
    bounds
        .into_iter()
        .map(|(bound, limit)| {
            let outcome = match measured.value(bound, &summary) {
                Ok(value) => Outcome::Measured {
                    value,
                    limit,
                    holds: value <= limit,
                    relation: "≤",
                },
                Err(reason) => Outcome::BadSpec(format!("check.{bound}: {reason}")),
            };
            Line {
                spec: name.clone(),
                bound: bound.to_string(),
                outcome,
                time,
            }
        })
        .chain(references)
        .collect()
}

/// Runs a study (`[study]`) and checks `min_order` against the observed order of each of its
/// curves (a scheme at fixed values of the other grid axes): one line per curve. The other
/// bounds measure single runs and are refused as a bad spec.
fn check_study(path: &Path, spec: &JobSpec) -> Vec<Line> {
    let name = path.display().to_string();
    let line = |bound: String, outcome, time| Line {
        spec: name.clone(),
        bound,
        outcome,
        time,
    };
    let check = spec.check.clone().unwrap_or_default();
    let single_run = check
        .bounds()
        .into_iter()
        .map(|(b, _)| b)
        .chain((!check.reference.is_empty()).then_some("reference"))
        .find(|b| *b != "min_order");
    if let Some(bound) = single_run {
        let reason = format!(
            "check.{bound}: a study checks min_order only (each run's bounds belong in a spec of its own)"
        );
        return vec![line(
            "spec".into(),
            Outcome::BadSpec(reason),
            Duration::ZERO,
        )];
    }
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let started = Instant::now();
    let report = crate::study::run_study(spec, path.parent(), threads, &|_| {});
    let time = started.elapsed();
    let report = match report {
        Ok(r) => r,
        Err(e) => {
            return vec![line(
                "run".into(),
                Outcome::RunFailed(format!("{e:#}")),
                time,
            )];
        }
    };
    let Some(limit) = check.min_order else {
        return vec![line("run".into(), Outcome::RunSucceeded, time)];
    };
    let orders = report.orders();
    if orders.is_empty() {
        let reason =
            "check.min_order: the study has no curve with two step sizes to fit an order on".into();
        return vec![line("spec".into(), Outcome::BadSpec(reason), time)];
    }
    orders
        .into_iter()
        .map(|o| {
            let at: Vec<String> = o.at.iter().map(|(k, v)| format!("{k}={v}")).collect();
            let curve = if at.is_empty() {
                o.scheme.clone()
            } else {
                format!("{}, {}", o.scheme, at.join(", "))
            };
            let outcome = Outcome::Measured {
                value: o.order,
                limit,
                holds: o.order >= limit,
                relation: "≥",
            };
            line(format!("min_order [{curve}]"), outcome, time)
        })
        .collect()
}

impl Line {
    /// `PASS spec bound value ≤ limit`, `FAIL …`, `ERROR …`.
    fn text(&self) -> String {
        match &self.outcome {
            Outcome::Measured {
                value,
                limit,
                holds,
                relation,
            } => format!(
                "{} {} {} = {value:.3e} (bound {relation} {limit:.3e})",
                if *holds { "PASS" } else { "FAIL" },
                self.spec,
                self.bound
            ),
            Outcome::RunSucceeded => {
                format!("PASS {} run succeeded (no [check] bounds)", self.spec)
            }
            Outcome::RunFailed(e) => format!("FAIL {} run failed: {e}", self.spec),
            Outcome::BadSpec(e) => format!("ERROR {} bad spec: {e}", self.spec),
        }
    }

    /// 0 pass, 1 fail, 2 bad spec.
    fn severity(&self) -> u8 {
        match &self.outcome {
            Outcome::Measured { holds: true, .. } | Outcome::RunSucceeded => 0,
            Outcome::Measured { holds: false, .. } | Outcome::RunFailed(_) => 1,
            Outcome::BadSpec(_) => 2,
        }
    }

    fn junit_case(&self) -> TestCase {
        let status = match self.severity() {
            0 => TestCaseStatus::success(),
            1 => {
                let mut s = TestCaseStatus::non_success(NonSuccessKind::Failure);
                s.set_message(self.text());
                s
            }
            _ => {
                let mut s = TestCaseStatus::non_success(NonSuccessKind::Error);
                s.set_message(self.text());
                s
            }
        };
        let mut case = TestCase::new(self.bound.clone(), status);
        case.set_classname(self.spec.clone());
        case.set_time(self.time);
        case
    }
}

/// Runs the command; the exit status travels as [`CheckExit`].
pub fn check(args: CheckArgs) -> Result<()> {
    let mut worst = 0u8;
    let mut suite = TestSuite::new("signorini check");
    for path in &args.specs {
        for line in check_one(path) {
            println!("{}", line.text());
            worst = worst.max(line.severity());
            suite.add_test_case(line.junit_case());
        }
    }
    if let Some(file) = &args.junit {
        let mut report = Report::new("signorini");
        report.add_test_suite(suite);
        let xml = report.to_string().context("writing the JUnit report")?;
        std::fs::write(file, xml).with_context(|| format!("writing {}", file.display()))?;
    }
    match worst {
        0 => Ok(()),
        code => Err(CheckExit(code).into()),
    }
}
