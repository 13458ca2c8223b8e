//! `signorini check`, the CI gate: exit 0 when every bound holds, 1 with a FAIL line when a bound
//! is too tight, 2 on a bad spec; the JUnit report it writes parses and says the same.

use quick_xml::Reader;
use quick_xml::events::Event;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn check(specs: &[PathBuf], junit: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_signorini"))
        .arg("check")
        .args(specs)
        .arg("--junit")
        .arg(junit)
        .output()
        .expect("running signorini check")
}

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(name)
}

/// The bouncing ball of examples/ with its `[check]` bounds replaced by `bounds`.
fn ball_with(dir: &Path, name: &str, bounds: &str) -> PathBuf {
    let text = std::fs::read_to_string(example("bouncing_ball.toml")).expect("reading the example");
    let base = text.split("\n[check]").next().expect("text before [check]");
    let base = base.replace("t_end = 10.0", "t_end = 2.0");
    let path = dir.join(name);
    std::fs::write(&path, format!("{base}\n[check]\n{bounds}\n")).expect("writing a spec");
    path
}

/// (test cases, failures, errors) per `<testcase>` of a JUnit file, read back with an XML parser.
fn junit_counts(path: &Path) -> (usize, usize, usize) {
    let xml = std::fs::read_to_string(path).expect("reading the JUnit file");
    let mut reader = Reader::from_str(&xml);
    let (mut cases, mut failures, mut errors) = (0, 0, 0);
    loop {
        match reader.read_event().expect("well-formed XML") {
            Event::Start(e) | Event::Empty(e) => match e.name().as_ref() {
                b"testcase" => cases += 1,
                b"failure" => failures += 1,
                b"error" => errors += 1,
                _ => {}
            },
            Event::Eof => break,
            _ => {}
        }
    }
    (cases, failures, errors)
}

/// Runs `signorini check` on `specs`, asserts that it exits 0 with `bounds` PASS lines and as
/// many passing JUnit cases, and returns its standard output.
fn all_pass(specs: &[PathBuf], bounds: usize) -> String {
    let dir = tempfile::tempdir().unwrap();
    let junit = dir.path().join("report.xml");
    let out = check(specs, &junit);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert_eq!(out.status.code(), Some(0), "stdout: {stdout}");
    assert_eq!(
        stdout.lines().filter(|l| l.starts_with("PASS ")).count(),
        bounds,
        "{stdout}"
    );
    assert_eq!(junit_counts(&junit), (bounds, 0, 0));
    stdout
}

#[test]
fn bounds_that_hold_exit_zero_with_pass_lines() {
    let specs = [
        example("bouncing_ball.toml"),
        example("chain.toml"),
        example("jay_negrut_test.toml"),
    ];
    // One line per bound: ball 2, chain 2, Jay–Negrut 1.
    let stdout = all_pass(&specs, 5);
    assert!(stdout.contains("max_balance_residual = "), "{stdout}");
}

#[test]
fn a_bound_too_tight_exits_one_with_a_fail_line() {
    let dir = tempfile::tempdir().unwrap();
    let junit = dir.path().join("report.xml");
    // Moreau–Jean θ = ½ closes the balance at ~2e-15, not 1e-20.
    let tight = ball_with(dir.path(), "tight.toml", "max_balance_residual = 1e-20");
    let out = check(&[tight], &junit);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "stdout: {stdout}");
    let line = stdout
        .lines()
        .find(|l| l.starts_with("FAIL "))
        .unwrap_or_else(|| panic!("no FAIL line: {stdout}"));
    assert!(
        line.contains("max_balance_residual") && line.contains("1.000e-20"),
        "{line}"
    );
    assert_eq!(junit_counts(&junit), (1, 1, 0));
}

#[test]
fn a_bad_spec_exits_two_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let junit = dir.path().join("report.xml");
    let negative = ball_with(dir.path(), "negative.toml", "max_balance_residual = -1.0");
    let unmeasurable = ball_with(dir.path(), "nonlinear_only.toml", "max_energy_error = 1e-3");
    let fine = ball_with(dir.path(), "fine.toml", "max_balance_residual = 1e-12");
    let out = check(&[fine, negative, unmeasurable], &junit);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(2), "stdout: {stdout}");
    assert!(
        stdout.contains("ERROR ") && stdout.contains("check.max_balance_residual"),
        "{stdout}"
    );
    assert!(
        stdout.contains("check.max_energy_error: this run reports no energy_error"),
        "{stdout}"
    );
    assert_eq!(junit_counts(&junit), (3, 0, 2));
}

/// A study checks `min_order` against each curve's observed order: generalized-α-SOI2 is second
/// order on the Jay–Negrut test problem (15), so 1.9 holds and 2.5 fails; a bound of a single run
/// in a study is a bad spec.
#[test]
fn a_study_checks_the_observed_order_of_each_curve() {
    let dir = tempfile::tempdir().unwrap();
    let junit = dir.path().join("report.xml");
    let study = |name: &str, bounds: &str| {
        let path = dir.path().join(name);
        let text = format!(
            r#"
[study]
reference = "exact"
error = "final"
[study.base]
model = {{ scene = "jay_negrut_test" }}
time = {{ h = 0.1, t_end = 1.0 }}
output = {{ probes = [0, 1] }}
[[study.schemes]]
scheme = "soi2_generalized_alpha"
rho_inf = 0.2
[study.grid]
"time.h" = [0.03125, 0.015625, 0.0078125, 0.00390625]
[check]
{bounds}
"#
        );
        std::fs::write(&path, text).unwrap();
        path
    };
    let out = check(&[study("holds.toml", "min_order = 1.9")], &junit);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{stdout}");
    let line = stdout.lines().next().expect("a line");
    assert!(line.starts_with("PASS "), "{line}");
    assert!(line.contains("min_order [soi2_generalized_alpha"), "{line}");
    let order: f64 = line
        .split(" = ")
        .nth(1)
        .and_then(|v| v.split(' ').next())
        .and_then(|v| v.parse().ok())
        .expect("the measured order");
    assert!((order - 2.0).abs() < 0.1, "{line}");
    assert_eq!(junit_counts(&junit), (1, 0, 0));

    let out = check(&[study("fails.toml", "min_order = 2.5")], &junit);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert!(stdout.starts_with("FAIL "), "{stdout}");
    assert_eq!(junit_counts(&junit), (1, 1, 0));

    let out = check(
        &[study(
            "bad.toml",
            "min_order = 1.9\nmax_balance_residual = 1e-12",
        )],
        &junit,
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(2), "{stdout}");
    assert!(
        stdout.contains("check.max_balance_residual: a study checks min_order only"),
        "{stdout}"
    );
}

/// The IFToMM benchmarks of `examples/benchmarks/` (docs/soi2.md) pass their `[check]` bounds:
/// the reference values of A01 (elliptic functions) and A02 (its parallelogram motion), the
/// joints on the manifold and the energy, A04 with its redundant joint, A05 (the stiff flyball
/// governor) against its independently integrated reference; one line per bound.
#[test]
fn the_multibody_benchmarks_pass_their_checks() {
    let specs: Vec<PathBuf> = [
        "a01_simple_pendulum",
        "a02_n_four_bar",
        "a04_bricard",
        "a05_flyball_governor",
    ]
    .iter()
    .map(|n| example(&format!("benchmarks/{n}.toml")))
    .collect();
    // A01: 2 bounds + 8 reference values; A02: 2 + 3; A04: 2; A05: 1 + 15.
    let stdout = all_pass(&specs, 33);
    assert!(stdout.contains("reference q_0 at t = 10"), "{stdout}");
    assert!(stdout.contains("reference v_0 at t = 7.5"), "{stdout}");
}

/// IFToMM A03, Andrews' squeezing mechanism (`examples/benchmarks/a03_andrews.toml`), passes its
/// `[check]`: the seven angles at t = 0.03 within 1e-4 rad of the Test Set for IVP solvers'
/// reference at h = 1e-5, the joints on the manifold; one PASS line per bound.
#[test]
fn andrews_mechanism_passes_its_check() {
    // 1 bound + 7 reference values.
    all_pass(&[example("benchmarks/a03_andrews.toml")], 8);
}

/// Issue 30's two new-user models (`examples/double_pendulum_rough_wall.toml`, the double
/// pendulum hitting a rough wall; `examples/disk_on_sinusoidal_floor.toml`, the disk rolling on a
/// wavy floor through `tangent_velocity`) pass the `[check]` bounds they document: the energy
/// error per step and the energies after each impact (−21.0 J at t = 2, −25.19 J at t = 3), the
/// rolling disk's energy kept, no work of friction and the disk still on the floor at t = 5.
#[test]
fn the_new_user_examples_pass_their_checks() {
    let specs = [
        example("double_pendulum_rough_wall.toml"),
        example("disk_on_sinusoidal_floor.toml"),
    ];
    // 1 bound + 3 reference values each.
    let stdout = all_pass(&specs, 8);
    assert!(stdout.contains("reference energy at t = 3"), "{stdout}");
}
