//! `signorini run --resume DIR`: a run killed with SIGKILL after a checkpoint continues from it
//! to the same steps.csv and summary.json as an uninterrupted run (byte for byte, the wall time
//! aside), and a rigid run to the same contacts.csv; a damaged checkpoint is reported and the run
//! starts again from step 0.

use serde_json::{Map, Value};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn signorini() -> Command {
    Command::new(env!("CARGO_BIN_EXE_signorini"))
}

/// A bar of 1000 elements for long enough (a few seconds) to be killed in the middle.
const SPEC: &str = r#"
name = "killed bar"
[model]
scene = "bar"
elements = 1000
gap = 0.001
initial_velocity = 1.0
[integrator]
scheme = "ns_generalized_alpha"
rho_inf = 0.8
[time]
h = 0.0002
steps = 60000
[output]
every = 37
probes = [500]
checkpoint_steps = 1500
"#;

fn run_whole(dir: &Path, spec: &Path) -> std::path::PathBuf {
    let out = dir.join("whole");
    let status = signorini()
        .args(["run", "--quiet", "--out"])
        .arg(&out)
        .arg(spec)
        .status()
        .unwrap();
    assert!(status.success());
    out
}

/// The summary without its wall time and rate.
fn summary(dir: &Path) -> Map<String, Value> {
    let text = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    let mut map: Map<String, Value> = serde_json::from_str(&text).unwrap();
    map.remove("wall_s");
    map.remove("steps_per_s");
    map
}

fn assert_same_results(a: &Path, b: &Path) {
    let (sa, sb) = (
        std::fs::read(a.join("steps.csv")).unwrap(),
        std::fs::read(b.join("steps.csv")).unwrap(),
    );
    assert!(sa == sb, "steps.csv differs");
    assert_eq!(summary(a), summary(b));
    for f in ["energy.svg", "residuals.svg"] {
        assert_eq!(
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
            "{f} differs"
        );
    }
    for gone in ["checkpoint.bin", "run_spec.json", "steps.csv.partial"] {
        assert!(!b.join(gone).exists(), "{gone} left after the run");
    }
}

/// Starts the run in `out` and kills it with SIGKILL once a checkpoint is on disk.
fn start_and_kill(spec: &Path, out: &Path) {
    let mut child = signorini()
        .args(["run", "--quiet", "--out"])
        .arg(out)
        .arg(spec)
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let started = Instant::now();
    while !out.join("checkpoint.bin").exists() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before its first checkpoint"
        );
        assert!(started.elapsed() < Duration::from_secs(120));
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(150));
    child.kill().unwrap(); // SIGKILL
    let status = child.wait().unwrap();
    assert!(!status.success(), "the run finished before it was killed");
    assert!(out.join("steps.csv.partial").exists());
    assert!(!out.join("summary.json").exists());
}

#[test]
fn a_killed_run_resumes_to_the_same_files() {
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("bar.toml");
    std::fs::write(&spec, SPEC).unwrap();
    let whole = run_whole(dir.path(), &spec);

    let out = dir.path().join("killed");
    start_and_kill(&spec, &out);
    let resumed = signorini()
        .arg("run")
        .arg("--resume")
        .arg(&out)
        .stdout(Stdio::null())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&resumed.stderr);
    assert!(resumed.status.success(), "{stderr}");
    assert!(stderr.contains("resuming"), "{stderr}");
    assert_same_results(&whole, &out);
}

#[test]
fn a_damaged_checkpoint_reruns_from_step_zero_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("bar.toml");
    std::fs::write(&spec, SPEC).unwrap();
    let whole = run_whole(dir.path(), &spec);

    let out = dir.path().join("killed");
    start_and_kill(&spec, &out);
    let path = out.join("checkpoint.bin");
    let mut bytes = std::fs::read(&path).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0xff;
    std::fs::write(&path, &bytes).unwrap();
    let resumed = signorini()
        .args(["run", "--quiet", "--resume"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&resumed.stderr);
    assert!(resumed.status.success(), "{stderr}");
    assert!(
        stderr.contains("checkpoint corrupted") && stderr.contains("rerunning from step 0"),
        "{stderr}"
    );
    assert_same_results(&whole, &out);
}

#[test]
fn resume_of_a_directory_without_a_run_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = signorini()
        .args(["run", "--resume"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("run_spec.json"), "{stderr}");
}

/// `examples/string_bridge.toml` made long enough to be killed (10⁶ steps, a record every 2 000,
/// a checkpoint every 20 000 steps): the banded contact solver's warm start and the
/// contact-region chart go through the checkpoint, and the resumed run ends with the same
/// files, `contact_region.svg` included.
#[test]
fn a_killed_string_on_its_bridge_resumes_to_the_same_files() {
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/string_bridge.toml");
    let text = std::fs::read_to_string(example).unwrap();
    let text = text
        .replace("t_end = 0.06", "t_end = 20.0")
        .replace("every = 5", "every = 2000\ncheckpoint_steps = 20000");
    assert!(text.contains("t_end = 20.0") && text.contains("checkpoint_steps"));
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("string_bridge.toml");
    std::fs::write(&spec, text).unwrap();
    let whole = run_whole(dir.path(), &spec);

    let out = dir.path().join("killed");
    start_and_kill(&spec, &out);
    let resumed = signorini()
        .arg("run")
        .arg("--resume")
        .arg(&out)
        .stdout(Stdio::null())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&resumed.stderr);
    assert!(resumed.status.success(), "{stderr}");
    assert!(stderr.contains("resuming"), "{stderr}");
    assert_same_results(&whole, &out);
    assert_eq!(
        std::fs::read(whole.join("contact_region.svg")).unwrap(),
        std::fs::read(out.join("contact_region.svg")).unwrap(),
        "contact_region.svg differs"
    );
}

/// `examples/rigid/box_stack.toml` made long enough to be killed (10⁵ steps, a record every
/// 1 000, a checkpoint every 10 000 steps) with the `contacts` table: the resumed run writes the
/// same contacts.csv as the uninterrupted one, the rows of the records before the checkpoint
/// included (issue 29: they were missing), and the same steps.csv and summary.
#[test]
fn a_killed_rigid_run_resumes_to_the_same_contacts_table() {
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/rigid/box_stack.toml");
    let text = std::fs::read_to_string(example).unwrap();
    let text = text.replace("t_end = 2.0", "t_end = 100.0").replace(
        "every = 10",
        "every = 1000\ncheckpoint_steps = 10000\ncontacts = true",
    );
    assert!(text.contains("t_end = 100.0") && text.contains("contacts = true"));
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("box_stack.toml");
    std::fs::write(&spec, text).unwrap();
    let whole = run_whole(dir.path(), &spec);

    let out = dir.path().join("killed");
    start_and_kill(&spec, &out);
    let resumed = signorini()
        .arg("run")
        .arg("--resume")
        .arg(&out)
        .stdout(Stdio::null())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&resumed.stderr);
    assert!(resumed.status.success(), "{stderr}");
    assert!(stderr.contains("resuming"), "{stderr}");
    let (sa, sb) = (
        std::fs::read(whole.join("steps.csv")).unwrap(),
        std::fs::read(out.join("steps.csv")).unwrap(),
    );
    assert!(sa == sb, "steps.csv differs");
    assert_eq!(summary(&whole), summary(&out));
    let (ca, cb) = (
        std::fs::read_to_string(whole.join("contacts.csv")).unwrap(),
        std::fs::read_to_string(out.join("contacts.csv")).unwrap(),
    );
    // 100 records after step 0, 12 contacts each (four corners under each box), and a header.
    assert_eq!(ca.lines().count(), 1 + 100 * 12);
    assert!(
        ca == cb,
        "contacts.csv differs: {} rows against {}",
        ca.lines().count(),
        cb.lines().count()
    );
}
