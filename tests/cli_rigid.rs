//! The rigid-bodies examples (issue 29) with a `[check]` pass `signorini check`: each one's bounds hold
//! (closed-form speeds and positions, the energy ledger at round-off).

use std::path::Path;
use std::process::Command;

#[test]
fn every_rigid_example_passes_its_check() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/rigid");
    let mut specs: Vec<_> = std::fs::read_dir(&dir)
        .expect("examples/rigid")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        // The benchmark scene (spheres_1000.toml, docs/rigid_benchmark.md) has no [check]: it is
        // timed by the bench, not checked.
        .filter(|p| {
            std::fs::read_to_string(p)
                .expect("example")
                .contains("\n[check]")
        })
        .collect();
    specs.sort();
    assert_eq!(specs.len(), 6, "{specs:?}");
    let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .arg("check")
        .args(&specs)
        .output()
        .expect("running signorini check");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Every example checks its ledger; none fails a bound.
    assert_eq!(stdout.matches("max_energy_error").count(), 6, "{stdout}");
    assert!(!stdout.contains("FAIL"), "{stdout}");
}
