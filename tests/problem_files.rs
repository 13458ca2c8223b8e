//! Friction problem files (`signorini::problem_file`, `signorini solve`): Siconos' files read to
//! the values Siconos reads (tests/fixtures/friction/siconos_values.json, made by
//! scripts/friction_fixtures.py with python3-siconos), our error equal to Siconos' at Siconos'
//! own solution, every storage format and both FCLib layouts round-trip, bad files are errors
//! naming the file, and `signorini solve` solves the fixtures and writes FCLib's `/solution`.
//! HDF5 is the optional feature `hdf5` (it links the system libhdf5): scripts/test.sh, hence CI,
//! runs these with it.
#![cfg(feature = "hdf5")]

use serde_json::Value;
use signorini::problem_file::fclib_layout::Datasets;
use signorini::problem_file::{self, RawProblem, dat, fclib};
use signorini_core::friction::{BlockCsr, Fc3dOptions, solve_fc3d};
use std::path::{Path, PathBuf};
use std::process::Command;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/friction")
}

fn reference() -> serde_json::Map<String, Value> {
    let text = std::fs::read_to_string(fixtures().join("siconos_values.json")).unwrap();
    serde_json::from_str::<Value>(&text)
        .unwrap()
        .as_object()
        .unwrap()
        .clone()
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) + 1e-300
}

fn dense(w: &BlockCsr) -> Vec<f64> {
    let n = w.size();
    let mut d = vec![0.0; n * n];
    for (i, j, x) in w.entries() {
        d[i * n + j] += x;
    }
    d
}

/// Every fixture reads to Siconos' dimension, contacts, q, μ and W entries (to the last bit for
/// `.dat` files, whose numbers both readers parse with the C library's and Rust's correctly
/// rounded conversions; 1e-12 for the HDF5 global reduction, summed in another order).
#[test]
fn siconos_files_read_to_the_values_siconos_reads() {
    let reference = reference();
    assert_eq!(reference.len(), 10);
    for (name, want) in &reference {
        let raw = problem_file::read(&fixtures().join(name)).unwrap_or_else(|e| panic!("{e}"));
        let rel = if want["reader"] == "siconos" {
            0.0
        } else {
            1e-12
        };
        assert_eq!(
            raw.dimension as u64,
            want["dimension"].as_u64().unwrap(),
            "{name}"
        );
        assert_eq!(
            raw.contacts() as u64,
            want["contacts"].as_u64().unwrap(),
            "{name}"
        );
        for (got, want) in raw.q.iter().zip(want["q_head"].as_array().unwrap()) {
            assert!(close(*got, f(want), rel), "{name}: q {got} against {want}");
        }
        let q_norm = raw.q.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(close(q_norm, f(&want["q_norm"]), 1e-13), "{name}: ‖q‖");
        for (got, want) in raw.mu.iter().zip(want["mu_head"].as_array().unwrap()) {
            assert_eq!(*got, f(want), "{name}: μ");
        }
        let n = raw.w.size();
        let d = dense(&raw.w);
        for e in want["w_entries"].as_array().unwrap() {
            let (i, j) = (
                e[0].as_u64().unwrap() as usize,
                e[1].as_u64().unwrap() as usize,
            );
            assert!(
                close(d[i * n + j], f(&e[2]), rel.max(1e-15)),
                "{name}: W[{i}][{j}] = {} against {}",
                d[i * n + j],
                e[2]
            );
        }
        let frobenius = d.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(
            close(frobenius, f(&want["w_frobenius"]), 1e-12),
            "{name}: ‖W‖_F"
        );
    }
}

/// Our error (the core's `natural_map_error`) is Siconos' error: at r = 0 and at the impulses
/// Siconos' NSGS returned, to 1e-9 relative (the two sum the squares in different orders).
#[test]
fn our_error_is_siconos_error_at_siconos_solution() {
    for (name, want) in &reference() {
        if want["reader"] != "siconos" {
            continue;
        }
        let raw = problem_file::read(&fixtures().join(name)).unwrap();
        let problem = raw.to_fc3d().unwrap();
        let lift = |v: &[f64]| -> Vec<f64> {
            if raw.dimension == 3 {
                return v.to_vec();
            }
            v.chunks(2).flat_map(|c| [c[0], c[1], 0.0]).collect()
        };
        let zero = vec![0.0; problem.q.len()];
        let at_zero = problem.error(&zero);
        assert!(
            close(at_zero, f(&want["error_at_zero"]), 1e-9),
            "{name}: {at_zero}"
        );
        let r: Vec<f64> = want["siconos_nsgs_r"]
            .as_array()
            .unwrap()
            .iter()
            .map(f)
            .collect();
        let ours = problem.error(&lift(&r));
        let theirs = f(&want["siconos_nsgs_error"]);
        // At a solution the error is a difference of nearly equal numbers: its round-off is
        // about 1e-16 in the error's normalised units whatever its size (Rover1039: 2.6931227e-13
        // against 2.6931362e-13 since the natural map takes √(t₁² + t₂²) instead of `hypot`).
        assert!(
            close(ours, theirs, 1e-6) || (ours - theirs).abs() <= 1e-15,
            "{name}: ours {ours:e}, Siconos {theirs:e}"
        );
    }
}

fn round_trip_dat(raw: &RawProblem, storage: &str) {
    let back = dat::parse(&dat::write(raw, storage)).unwrap();
    assert_eq!(back.dimension, raw.dimension);
    assert_eq!(back.q, raw.q, "{storage}");
    assert_eq!(back.mu, raw.mu, "{storage}");
    assert_eq!(dense(&back.w), dense(&raw.w), "{storage}");
}

/// Each `.dat` storage (dense, sparse block, CSparse) and FCLib's local layout round-trip a 3D
/// and a 2D problem exactly (write, read, equal).
#[test]
fn every_storage_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["Rover1039.dat", "FrictionContactProblem00031.dat"] {
        let raw = problem_file::read(&fixtures().join(name)).unwrap();
        for storage in ["dense", "sparse_block", "csparse"] {
            round_trip_dat(&raw, storage);
        }
        let path = dir.path().join(format!("{name}.hdf5"));
        fclib::write_local(&path, &raw).unwrap();
        let back = problem_file::read(&path).unwrap();
        assert_eq!(
            (back.dimension, &back.q, &back.mu),
            (raw.dimension, &raw.q, &raw.mu)
        );
        assert_eq!(dense(&back.w), dense(&raw.w));
    }
}

/// FCLib's global layout: a diagonal M and H written, read back as its local reduction
/// W = Hᵀ M⁻¹ H, q = Hᵀ M⁻¹ f + w, computed here by hand.
#[test]
fn global_layout_round_trips_through_its_local_reduction() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("global.hdf5");
    // Two dofs of mass 2 and 4, one 3D contact: H (2×3).
    let mass = [2.0, 4.0];
    let h = [(0, 0, 1.0), (1, 0, 0.5), (0, 1, -1.0), (1, 2, 2.0)];
    let (fv, w, mu) = ([1.0, -8.0], [0.1, 0.2, 0.3], [0.6]);
    fclib::write_datasets(&path, &Datasets::global(3, &mass, &h, &fv, &w, &mu)).unwrap();
    let raw = problem_file::read(&path).unwrap();
    // Columns of H: c0 = (1, 0.5), c1 = (−1, 0), c2 = (0, 2); W_ab = Σ_k H_ka H_kb / M_k.
    let expected = [0.5 + 0.0625, -0.5, 0.25, -0.5, 0.5, 0.0, 0.25, 0.0, 1.0];
    assert_eq!(dense(&raw.w), expected);
    // q = Hᵀ M⁻¹ f + w: M⁻¹ f = (0.5, −2).
    for (got, want) in raw.q.iter().zip([0.5 - 1.0 + 0.1, -0.5 + 0.2, -4.0 + 0.3]) {
        assert!(close(*got, want, 1e-15), "q = {:?}", raw.q);
    }
    assert_eq!(raw.mu, vec![0.6]);
}

/// Bad files are errors that name the file and the reason, never a panic.
#[test]
fn bad_files_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &[u8], &str); 6] = [
        (
            "truncated.dat",
            b"3\n1\n0\n3\n3\n3\t3\n1\n0\n",
            "ends before",
        ),
        (
            "letters.dat",
            b"3\n1\n0\n3\n3\n3 3\n1 0 x",
            "should be a number",
        ),
        ("dimension.dat", b"4\n1\n0\n4\n4\n", "dimension is 4"),
        ("size.dat", b"3\n2\n0\n3\n3\n3 3\n", "W is 3×3"),
        ("storage.dat", b"3\n1\n7\n3\n3\n", "unknown storage 7"),
        ("fake.hdf5", b"\x89HDF\r\n\x1a\nnot really", "HDF5"),
    ];
    for (name, text, reason) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let e = problem_file::read(&path).unwrap_err().to_string();
        assert!(e.contains(name) && e.contains(reason), "{e}");
    }
    let missing = problem_file::read(&dir.path().join("missing.dat")).unwrap_err();
    assert!(missing.to_string().contains("missing.dat"));
    // A global `.dat` problem (Siconos' gfc2d format) is refused by its size, not misread.
    let global = dir.path().join("gfc2d.dat");
    std::fs::write(&global, "2\n69\n2\n900\n900\n1\n").unwrap();
    assert!(
        problem_file::read(&global)
            .unwrap_err()
            .to_string()
            .contains("W is 900×900")
    );
}

/// `signorini solve --json` on the fixtures: every problem that Siconos' NSGS solved at 1e-10
/// is solved by `auto` at 1e-8, with one JSON line of the fields of docs/friction_benchmark.md each, and
/// `--out` writes FCLib's `/solution` whose r has that error.
#[test]
fn solve_command_solves_the_fixtures_and_writes_solutions() {
    let dir = tempfile::tempdir().unwrap();
    let files = [
        "Rover1039.dat",
        "FrictionContact3D_1c.dat",
        "Confeti-ex13-4contact-Fc3D-SBM.dat",
        "FrictionContactProblem00394.dat",
        "FrictionContactProblem00031.dat",
    ];
    let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .arg("solve")
        .args(files.iter().map(|f| fixtures().join(f)))
        .args(["--json", "--tolerance", "1e-8", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), files.len());
    for (line, file) in lines.iter().zip(files) {
        for key in [
            "file",
            "dimension",
            "contacts",
            "solver",
            "converged",
            "iterations",
            "error",
            "seconds",
        ] {
            assert!(line.get(key).is_some(), "{file}: {key} missing in {line}");
        }
        assert_eq!(line["converged"], true, "{line}");
        assert!(f(&line["error"]) <= 1e-8, "{line}");
        let stem = file.trim_end_matches(".dat");
        let (r, _u) = fclib::read_solution(&dir.path().join(format!("{stem}.hdf5"))).unwrap();
        let raw = problem_file::read(&fixtures().join(file)).unwrap();
        let problem = raw.to_fc3d().unwrap();
        let lifted: Vec<f64> = if raw.dimension == 3 {
            r
        } else {
            r.chunks(2).flat_map(|c| [c[0], c[1], 0.0]).collect()
        };
        assert!(problem.error(&lifted) <= 1e-8, "{file}");
        let direct = solve_fc3d(&problem, &Fc3dOptions::default()).unwrap();
        assert_eq!(direct.solver, line["solver"].as_str().unwrap(), "{file}");
    }
    // A bad file among good ones: reported by name, the others still solved, exit status 1.
    let bad = dir.path().join("bad.dat");
    std::fs::write(&bad, "3\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .arg("solve")
        .arg(&bad)
        .arg(fixtures().join("Rover1039.dat"))
        .arg("--json")
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("bad.dat"));
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 1);
}

/// `signorini solve --warm-start` starts each solve from `FILE.start` (the rigid bench's
/// `--dump` writes one): from the problem's own solution Gauss–Seidel stops after one sweep, where
/// from r = 0 it needs more; a start of the wrong length and a missing one are errors naming the
/// file, and the other files are still solved.
#[test]
fn solve_command_starts_from_the_file_next_to_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("Rover1039.dat");
    std::fs::copy(fixtures().join("Rover1039.dat"), &file).unwrap();
    let problem = problem_file::read(&file).unwrap().to_fc3d().unwrap();
    let options = Fc3dOptions {
        kind: signorini_core::friction::Fc3dSolverKind::Nsgs,
        tolerance: 1e-12,
        ..Fc3dOptions::default()
    };
    let solution = solve_fc3d(&problem, &options).unwrap();
    assert!(solution.iterations > 1, "{}", solution.iterations);
    let start: String = solution.r.iter().map(|x| format!("{x:e}\n")).collect();
    std::fs::write(dir.path().join("Rover1039.dat.start"), start).unwrap();
    let solve = |files: &[&Path]| {
        Command::new(env!("CARGO_BIN_EXE_signorini"))
            .arg("solve")
            .args(files)
            .args([
                "--solver",
                "nsgs",
                "--tolerance",
                "1e-8",
                "--warm-start",
                "--json",
            ])
            .output()
            .unwrap()
    };
    let out = solve(&[&file]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(line["iterations"], 1, "{line}");
    assert_eq!(line["converged"], true, "{line}");
    // A start one number short, and a problem without a start.
    let short = dir.path().join("short.dat");
    std::fs::copy(&file, &short).unwrap();
    let numbers = solution.r.len() - 1;
    let text: String = solution.r[..numbers]
        .iter()
        .map(|x| format!("{x:e}\n"))
        .collect();
    std::fs::write(dir.path().join("short.dat.start"), text).unwrap();
    let alone = dir.path().join("alone.dat");
    std::fs::copy(&file, &alone).unwrap();
    let out = solve(&[&short, &alone, &file]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("short.dat"), "{stderr}");
    assert!(stderr.contains("alone.dat.start"), "{stderr}");
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 1);
}

/// `--repeat N` solves N times and reports the fastest time next to the first; the answer is
/// the single solve's (the solvers are deterministic). `--repeat 0` is refused by name.
#[test]
fn solve_command_repeats_a_solve_and_reports_the_fastest() {
    let solve = |repeat: &str| {
        Command::new(env!("CARGO_BIN_EXE_signorini"))
            .arg("solve")
            .arg(fixtures().join("Rover1039.dat"))
            .args(["--json", "--solver", "prox", "--repeat", repeat])
            .output()
            .unwrap()
    };
    let line = |out: &std::process::Output| -> Value {
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_str(String::from_utf8_lossy(&out.stdout).trim()).unwrap()
    };
    let once = line(&solve("1"));
    let five = line(&solve("5"));
    assert_eq!(five["repeat"], 5);
    assert!(f(&five["seconds"]) <= f(&five["seconds_first"]), "{five}");
    assert_eq!(once["seconds"], once["seconds_first"], "{once}");
    for key in ["solver", "iterations", "error"] {
        assert_eq!(once[key], five[key], "{key}");
    }
    let refused = solve("0");
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--repeat"));
}
