//! `signorini run` end to end: the examples run and produce consistent files; bad input is
//! refused with a message naming the field, a non-zero exit, and no result files.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn signorini() -> Command {
    Command::new(env!("CARGO_BIN_EXE_signorini"))
}

fn run_spec(dir: &Path, name: &str, spec: &str) -> (Output, PathBuf) {
    let spec_path = dir.join(name);
    std::fs::write(&spec_path, spec).unwrap();
    let out = dir.join("out");
    let output = signorini()
        .arg("run")
        .arg(&spec_path)
        .arg("--out")
        .arg(&out)
        .arg("--quiet")
        .output()
        .unwrap();
    (output, out)
}

/// Runs a bad spec and checks: exit status non-zero, stderr names `field`, no result files.
fn assert_refused(spec: &str, field: &str, reason_fragment: &str) {
    let dir = tempfile::tempdir().unwrap();
    // A stale result from an earlier run must not survive a failed one either.
    let out = dir.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("summary.json"), "{\"stale\": true}").unwrap();
    let name = if spec.trim_start().starts_with('{') {
        "spec.json"
    } else {
        "spec.toml"
    };
    let (output, out) = run_spec(dir.path(), name, spec);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        !output.status.success(),
        "accepted a bad spec; stderr: {stderr}"
    );
    assert!(
        stderr.contains(field),
        "stderr does not name `{field}`: {stderr}"
    );
    assert!(
        stderr.contains(reason_fragment),
        "stderr does not say `{reason_fragment}`: {stderr}"
    );
    for f in ["steps.csv", "summary.json", "steps.csv.partial"] {
        assert!(
            !out.join(f).exists(),
            "{f} left behind after a refused spec"
        );
    }
}

const BALL_TIME: &str = "[time]\nh = 0.01\nsteps = 10\n";

#[test]
fn mass_not_positive_definite() {
    assert_refused(
        "[model]\nscene = \"linear\"\nmass = [[1.0, 2.0], [2.0, 1.0]]\n[time]\nh = 0.01\nsteps = 10\n",
        "model.mass",
        "not symmetric positive definite",
    );
}

#[test]
fn mass_not_symmetric() {
    assert_refused(
        "[model]\nscene = \"linear\"\nmass = [[1.0, 0.5], [0.0, 1.0]]\n[time]\nh = 0.01\nsteps = 10\n",
        "model.mass",
        "not symmetric",
    );
}

#[test]
fn stiffness_not_semidefinite() {
    assert_refused(
        "[model]\nscene = \"linear\"\nmass = [[1.0, 0.0], [0.0, 1.0]]\nstiffness = [[1.0, 2.0], [2.0, 1.0]]\n[time]\nh = 0.01\nsteps = 10\n",
        "model.stiffness",
        "not positive semidefinite",
    );
}

#[test]
fn dimension_mismatch() {
    assert_refused(
        "[model]\nscene = \"linear\"\nmass = [[1.0, 0.0], [0.0, 1.0]]\nq0 = [0.0, 0.0, 1.0]\n[time]\nh = 0.01\nsteps = 10\n",
        "model.q0",
        "expected 2 entries, got 3",
    );
}

#[test]
fn nan_entry() {
    assert_refused(
        "[model]\nscene = \"linear\"\nmass = [[1.0, 0.0], [0.0, nan]]\n[time]\nh = 0.01\nsteps = 10\n",
        "model.mass",
        "not finite",
    );
}

#[test]
fn infinite_entry() {
    assert_refused(
        &format!("[model]\nscene = \"bouncing_ball\"\nv0 = -inf\n{BALL_TIME}"),
        "model.v0",
        "not finite",
    );
}

#[test]
fn non_positive_step() {
    assert_refused(
        "[model]\nscene = \"bouncing_ball\"\n[time]\nh = 0.0\nsteps = 10\n",
        "time.h",
        "> 0",
    );
    assert_refused(
        "[model]\nscene = \"bouncing_ball\"\n[time]\nh = -0.1\nsteps = 10\n",
        "time.h",
        "> 0",
    );
}

#[test]
fn negative_end_time() {
    assert_refused(
        "[model]\nscene = \"bouncing_ball\"\n[time]\nh = 0.01\nt_end = -1.0\n",
        "time.t_end",
        "≥ 0",
    );
}

#[test]
fn more_steps_than_exact_step_times() {
    assert_refused(
        "[model]\nscene = \"bouncing_ball\"\n[time]\nh = 1e-3\nt_end = 1e300\n",
        "time.t_end",
        "more than 2⁵³",
    );
    assert_refused(
        "[model]\nscene = \"bouncing_ball\"\n[time]\nh = 1e-3\nsteps = 9007199254740993\n",
        "time.steps",
        "more than 2⁵³",
    );
    assert_refused(
        "[model]\nscene = \"pendulum\"\n[integrator]\nscheme = \"soi2_hht\"\n[time]\nh = 1e-9\nt_end = 1e300\n",
        "time.t_end",
        "more than 2⁵³",
    );
}

/// Sizes are checked before anything is allocated: these specs asked for 80 GB (a triplet far
/// off the diagonal), 1.2 GB (a chain of 12 000 masses; 29 GB at 60 000) or 16 GB (10⁹
/// elements), and the process aborted.
#[test]
fn models_too_large_to_store() {
    assert_refused(
        "[model]\nscene = \"linear\"\nmass_triplets = [[0, 0, 1.0], [99999, 99999, 1.0], [0, 99999, 0.1]]\n[time]\nh = 1e-3\nsteps = 1\n",
        "model.mass_triplets",
        "stored entries",
    );
    // One contact per mass: 12 000 contacts need a dense 12 000 × 12 000 Delassus operator
    // when a dense solver is asked for (`auto` takes the banded solver for them since issue 19).
    let n = 12_000;
    let list = |x: &str| vec![x; n].join(", ");
    let positions: Vec<String> = (0..n)
        .map(|i| format!("{}", 0.1 + 0.01 * i as f64))
        .collect();
    assert_refused(
        &format!(
            "[model]\nscene = \"chain\"\nmasses = [{}]\npositions = [{}]\nvelocities = [{}]\n[contact_solver]\nkind = \"lemke\"\n[time]\nh = 1e-3\nsteps = 1\n",
            list("1.0"),
            positions.join(", "),
            list("0.0")
        ),
        "model.contacts",
        "12000 contacts",
    );
    for scheme in ["moreau_jean", "wfem"] {
        assert_refused(
            &format!(
                "[model]\nscene = \"bar\"\nelements = 1000000000\n[integrator]\nscheme = \"{scheme}\"\n[time]\nh = 1e-3\nsteps = 1\n"
            ),
            "model.elements",
            "[1, 10⁷]",
        );
    }
}

#[test]
fn theta_outside_unit_interval() {
    assert_refused(
        &format!(
            "[model]\nscene = \"bouncing_ball\"\n[integrator]\nscheme = \"moreau_jean\"\ntheta = 1.5\n{BALL_TIME}"
        ),
        "integrator.theta",
        "[0, 1]",
    );
}

#[test]
fn restitution_outside_unit_interval() {
    assert_refused(
        &format!("[model]\nscene = \"bouncing_ball\"\nrestitution = 1.2\n{BALL_TIME}"),
        "model.restitution",
        "[0, 1]",
    );
    assert_refused(
        "[model]\nscene = \"chain\"\nrestitution = -0.1\n[time]\nh = 0.01\nsteps = 10\n",
        "model.restitution",
        "[0, 1]",
    );
}

#[test]
fn unknown_field() {
    assert_refused(
        &format!("[model]\nscene = \"bouncing_ball\"\nmas = 2.0\n{BALL_TIME}"),
        "model.mas",
        "unknown field",
    );
    assert_refused(
        r#"{"model": {"scene": "bouncing_ball"}, "time": {"h": 0.01, "steps": 10, "stpes": 3}}"#,
        "time.stpes",
        "unknown field",
    );
}

#[test]
fn unknown_scene() {
    assert_refused(
        &format!("[model]\nscene = \"trampoline\"\n{BALL_TIME}"),
        "model.scene",
        "unknown variant",
    );
}

#[test]
fn example_specs_run_and_their_files_agree() {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    for name in ["bouncing_ball", "bar", "chain", "linear", "dep_bar"] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join(name);
        let status = signorini()
            .args(["run", "--quiet", "--out"])
            .arg(&out)
            .arg(examples.join(format!("{name}.toml")))
            .status()
            .unwrap();
        assert!(status.success(), "{name} failed");
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        for key in [
            "steps",
            "wall_s",
            "steps_per_s",
            "max_abs_balance_residual",
            "energy_initial",
            "energy_final",
            "energy_max",
            "impacts",
            "lcp_max_error",
        ] {
            assert!(summary.get(key).is_some(), "{name}: summary lacks {key}");
        }
        let csv = std::fs::read_to_string(out.join("steps.csv")).unwrap();
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(&header[..4], &["step", "t", "kinetic", "strain"]);
        assert!(header.contains(&"gap_0") && header.contains(&"u_0") && header.contains(&"p_0"));
        let residual = header
            .iter()
            .position(|c| *c == "balance_residual")
            .unwrap();
        let energy = header.iter().position(|c| *c == "energy").unwrap();
        let rows: Vec<Vec<f64>> = lines
            .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
            .collect();
        // The summary's maximum is the maximum over every step; the recorded rows are a subset.
        let max_row = rows.iter().map(|r| r[residual].abs()).fold(0.0, f64::max);
        let max_summary = summary["max_abs_balance_residual"].as_f64().unwrap();
        assert!(max_row <= max_summary);
        assert!(
            max_summary <= 1e-10 * summary["energy_max"].as_f64().unwrap().max(1.0),
            "{name}: {max_summary:e}"
        );
        assert_eq!(
            rows.last().unwrap()[0] as u64,
            summary["steps"].as_u64().unwrap()
        );
        assert_eq!(
            rows.first().unwrap()[energy],
            summary["energy_initial"].as_f64().unwrap()
        );
    }
}

/// `signorini compare`: two runs of the ball (Moreau–Jean, nonsmooth Newmark) give one figure
/// per column with a curve and a legend entry per run, and a table whose values are the runs'
/// summary.json values; a directory without steps and an unknown column are refused by name.
#[test]
fn compare_draws_one_curve_per_run_and_tabulates_the_summaries() {
    let dir = tempfile::tempdir().unwrap();
    let mut outs = Vec::new();
    for (name, integrator) in [
        ("mj", "scheme = \"moreau_jean\"\ntheta = 0.5"),
        ("nm", "scheme = \"ns_newmark\"\nbeta = 0.25\ngamma = 0.5"),
    ] {
        let spec = format!(
            "[model]\nscene = \"bouncing_ball\"\nrestitution = 0.8\n[integrator]\n{integrator}\n[time]\nh = 0.01\nt_end = 3.0\n"
        );
        let spec_path = dir.path().join(format!("{name}.toml"));
        std::fs::write(&spec_path, spec).unwrap();
        let out = dir.path().join(name);
        let status = signorini()
            .args(["run", "--quiet", "--out"])
            .arg(&out)
            .arg(&spec_path)
            .status()
            .unwrap();
        assert!(status.success());
        outs.push(out);
    }
    let cmp = dir.path().join("cmp");
    let output = signorini()
        .arg("compare")
        .args(&outs)
        .args([
            "--column",
            "energy",
            "--column",
            "balance_residual",
            "--out",
        ])
        .arg(&cmp)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let labels = ["mj: moreau_jean, h = 0.01", "nm: ns_newmark, h = 0.01"];
    for column in ["energy", "balance_residual"] {
        let svg = std::fs::read_to_string(cmp.join(format!("compare_{column}.svg"))).unwrap();
        // One colour of curve per run (a residual curve breaks where the value is exactly 0).
        let strokes: std::collections::BTreeSet<&str> = svg
            .split("<polyline")
            .skip(1)
            .filter_map(|p| p.split("stroke=\"").nth(1)?.split('"').next())
            .collect();
        assert_eq!(strokes.len(), 2, "{column}: {strokes:?}");
        for l in labels {
            assert!(
                svg.contains(&format!(">{l}</text>")),
                "{column}: legend {l}"
            );
        }
    }
    let csv = std::fs::read_to_string(cmp.join("compare.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header[0], "run");
    for ((line, out), label) in lines.zip(&outs).zip(labels) {
        assert!(line.starts_with(&format!("\"{label}\",")), "{line}");
        assert!(stdout.contains(label));
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        let cells: Vec<&str> = line.rsplitn(header.len(), ',').collect();
        // rsplitn yields the numbers from the right, then the quoted label (it has commas).
        for (cell, field) in cells.iter().rev().skip(1).zip(&header[1..]) {
            let want = summary[*field].as_f64().unwrap();
            assert_eq!(cell.parse::<f64>().unwrap(), want, "{label}: {field}");
        }
    }

    // An analysis records no steps; a column must exist in every run.
    let analysis = dir.path().join("modes");
    std::fs::create_dir_all(&analysis).unwrap();
    std::fs::write(analysis.join("summary.json"), "{}").unwrap();
    let refused = |args: &[&std::path::Path], column: &str, says: &str| {
        let output = signorini()
            .arg("compare")
            .args(args)
            .args(["--column", column, "--out"])
            .arg(&cmp)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success());
        assert!(stderr.contains(says), "{stderr}");
    };
    refused(&[&outs[0], &analysis], "energy", "no step table");
    refused(&[&outs[0], &outs[1]], "kinetc", "no column \"kinetc\"");
}

/// `signorini schema` prints the JSON Schema of job specs: valid JSON naming every scene and
/// scheme, the same document `--out` writes.
#[test]
fn schema_command_prints_the_spec_schema() {
    let out = signorini().arg("schema").output().expect("running schema");
    assert!(out.status.success(), "{out:?}");
    let schema: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(schema["title"], "JobSpec");
    let text = String::from_utf8_lossy(&out.stdout);
    for name in [
        "\"bouncing_ball\"",
        "\"soi2_hht\"",
        "\"nonsmooth_modes\"",
        "\"activation_gamma\"",
    ] {
        assert!(text.contains(name), "{name} missing");
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("signorini.schema.json");
    let status = signorini()
        .args(["schema", "--out"])
        .arg(&path)
        .status()
        .expect("running schema --out");
    assert!(status.success());
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(written, schema);
}

/// `scene = "lagrangian"` from the CLI: the user-model examples run (the energy columns of the
/// SOI2 schemes, the joints at round-off), and a misspelt name is refused naming its field.
#[test]
fn lagrangian_examples_run_and_a_bad_expression_is_refused() {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    for name in ["pendulum_lagrangian", "double_pendulum_cartesian"] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join(name);
        let status = signorini()
            .args(["run", "--quiet", "--out"])
            .arg(&out)
            .arg(examples.join(format!("{name}.toml")))
            .status()
            .unwrap();
        assert!(status.success(), "{name} failed");
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        assert_eq!(summary["scene"], "lagrangian", "{name}");
        assert!(
            summary["max_position_residual"].as_f64().unwrap() < 1e-12,
            "{name}"
        );
        let csv = std::fs::read_to_string(out.join("steps.csv")).unwrap();
        let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        for c in ["kinetic", "potential", "energy", "lambda_1"] {
            assert!(header.contains(&c), "{name}: no column {c} in {header:?}");
        }
    }
    let text = std::fs::read_to_string(examples.join("pendulum_lagrangian.toml")).unwrap();
    assert_refused(
        &text.replace("\"m*g*y + k/2", "\"m*gg*y + k/2"),
        "model.potential",
        "unknown name 'gg' at 2 (did you mean 'g'?)",
    );
}

/// Issue 30: silent nonsense is refused naming the field: a step longer than the run (h = 10
/// with t_end = 5 ran one step to t = 10), and a start inside the obstacle (a gap of −0.37 at
/// q0 ran with the model stuck inside the wall).
#[test]
fn a_step_longer_than_the_run_and_a_start_inside_the_wall_are_refused() {
    assert_refused(
        &format!(
            "[model]\nscene = \"bouncing_ball\"\n[time]\nh = 10.0\nt_end = 5.0\n{}",
            ""
        ),
        "time.h",
        "longer than t_end",
    );
    assert_refused(
        "[model]\nscene = \"lagrangian\"\ncoordinates = [\"x\", \"y\"]\nmass = [[1, 0], [0, 1]]\npotential = \"9.81*y\"\nq0 = [0.2, -0.37]\n[[model.contacts]]\ngap = \"y\"\n[integrator]\nscheme = \"moreau_jean\"\n[time]\nh = 0.01\nt_end = 0.1\n",
        "model.contacts[0].gap",
        "-3.7e-1 < 0 at q0",
    );
}

/// Issue 30: `signorini run` applies the server's default size limits (10⁸ steps here: the CLI
/// took t_end = 1e6 with h = 1e-9 and wrote 680 MB of CSV where the server refuses), and
/// `--no-limits` lifts them. The lifted run fails at its first step (a force that turns NaN
/// at t = 1e-9): its summary says why, naming the value, its entry and the state, and the
/// rows recorded before the failure stay in steps.csv.
#[test]
fn the_cli_honours_the_size_limits_and_a_failed_run_keeps_its_rows() {
    let spec = "[model]\nscene = \"lagrangian\"\ncoordinates = [\"x\"]\nmass = [[1]]\nforces = [\"sqrt(0.5e-9 - t)\"]\nq0 = [0.25]\nv0 = [1.5]\n[[model.contacts]]\ngap = \"x + 1\"\n[integrator]\nscheme = \"moreau_jean\"\n[time]\nh = 1e-9\nt_end = 1.0\n";
    assert_refused(spec, "time", "exceed this server's limit of 100000000");
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("spec.toml"), spec).unwrap();
    let out = dir.path().join("out");
    let output = signorini()
        .arg("run")
        .arg(dir.path().join("spec.toml"))
        .arg("--out")
        .arg(&out)
        .arg("--quiet")
        .arg("--no-limits")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("run failed: step 1"), "{stderr}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["status"], "failed", "{summary}");
    let error = summary["error"].as_str().unwrap();
    assert!(
        error.contains("F(t, q, v) is not finite (entry 0 is NaN) at q = [0.25"),
        "{error}"
    );
    assert!(error.contains("v = [1.5]"), "{error}");
    let csv = std::fs::read_to_string(out.join("steps.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows.len(), 2, "the header and step 0: {csv}");
    assert!(rows[0].starts_with("step,t,"), "{csv}");
    assert!(rows[1].starts_with("0,0.0,"), "{csv}");
}

/// Issue 30: `compare` of two `lagrangian` runs draws and tabulates their energy error (it
/// defaulted to `balance_residual`, which they do not have, and its table had an empty
/// balance-residual column).
#[test]
fn compare_shows_the_energy_error_of_lagrangian_runs() {
    let dir = tempfile::tempdir().unwrap();
    let mut outs = Vec::new();
    for (name, h) in [("coarse", "0.002"), ("fine", "0.001")] {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/pendulum_wall.toml"),
        )
        .unwrap();
        let mut spec: toml::Value = toml::from_str(&text).unwrap();
        spec["time"]["h"] = toml::Value::Float(h.parse().unwrap());
        spec["time"]["t_end"] = toml::Value::Float(1.0);
        let (output, _) = run_spec(
            dir.path(),
            &format!("{name}.toml"),
            &toml::to_string(&spec).unwrap(),
        );
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let out = dir.path().join(name);
        std::fs::rename(dir.path().join("out"), &out).unwrap();
        outs.push(out);
    }
    let cmp = dir.path().join("cmp");
    let output = signorini()
        .arg("compare")
        .args(&outs)
        .arg("--out")
        .arg(&cmp)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let svg = std::fs::read_to_string(cmp.join("compare_energy_error.svg")).unwrap();
    assert_eq!(svg.matches("<polyline").count(), 2, "one curve per run");
    let csv = std::fs::read_to_string(cmp.join("compare.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert!(header.contains(&"max_abs_energy_error"), "{header:?}");
    assert!(!header.contains(&"max_abs_balance_residual"), "{header:?}");
    let at = header
        .iter()
        .position(|f| *f == "max_abs_energy_error")
        .unwrap();
    for (line, out) in lines.zip(&outs) {
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        let cells: Vec<&str> = line.rsplitn(header.len(), ',').collect();
        let cell = cells[header.len() - 1 - at];
        let want = summary["max_abs_energy_error"].as_f64().unwrap();
        assert!(want > 0.0);
        assert_eq!(cell.parse::<f64>().unwrap(), want, "{line}");
    }
}
