//! docs/tutorial.md cannot go stale: its files (the ```` ```toml file=NAME ```` blocks) are
//! written to a fresh directory and every `signorini` command of its `sh` blocks is run there
//! with this build's binary, each to exit status 0; the figures it names are made, and the
//! numbers it quotes from `summary.json` and `signorini check` are what the commands print.
//! Its `curl` and Python parts need a server and the installed Python client:
//! `clients/python/tests/test_tutorial.py` runs them the same way.

use std::path::Path;
use std::process::Command;

/// The ```` ```INFO ```` blocks of `markdown`, as (info string, body).
fn blocks(markdown: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut open: Option<(String, String)> = None;
    for line in markdown.lines() {
        match (&mut open, line.strip_prefix("```")) {
            (None, Some(info)) => open = Some((info.trim().to_string(), String::new())),
            (Some(_), Some(_)) => out.extend(open.take()),
            (Some((_, body)), None) => {
                body.push_str(line);
                body.push('\n');
            }
            (None, None) => {}
        }
    }
    out
}

#[test]
fn the_tutorials_commands_run_and_print_what_it_quotes() {
    let page =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/tutorial.md"))
            .expect("docs/tutorial.md");
    let dir = tempfile::tempdir().expect("tempdir");
    let mut commands = Vec::new();
    for (info, body) in blocks(&page) {
        if let Some(name) = info.strip_prefix("toml file=") {
            std::fs::write(dir.path().join(name), &body).expect("writing a file of the page");
        } else if info == "sh" {
            commands.extend(
                body.lines()
                    .filter(|l| l.starts_with("signorini "))
                    .map(String::from),
            );
        }
    }
    assert!(commands.len() >= 3, "{commands:?}");
    let mut printed = String::new();
    for command in &commands {
        let args: Vec<&str> = command.split_whitespace().skip(1).collect();
        let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
            .args(&args)
            .current_dir(dir.path())
            .output()
            .expect("signorini");
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{command}: {}\n{stdout}",
            String::from_utf8_lossy(&out.stderr)
        );
        printed.push_str(&stdout);
    }
    // What step 2 says of the run.
    let run = dir.path().join("out/pendulum");
    for figure in ["energy", "residuals", "coordinates", "gaps", "impulses"] {
        assert!(run.join(format!("{figure}.svg")).is_file(), "{figure}.svg");
    }
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(run.join("summary.json")).expect("summary.json"),
    )
    .expect("JSON");
    assert_eq!(summary["impacts"], 3);
    let quoted = format!("\"energy_final\": {}", summary["energy_final"]);
    assert!(page.contains(&quoted), "the page does not quote {quoted}");
    // Step 3's line, and step 6's outputs.
    assert!(
        page.contains(&format!(
            "\n{}\n",
            printed
                .lines()
                .find(|l| l.starts_with("PASS pendulum.toml"))
                .expect("a PASS line")
        )),
        "{printed}"
    );
    for file in ["study.csv", "work_precision.svg", "summary.json"] {
        assert!(dir.path().join("out/study").join(file).is_file(), "{file}");
    }
}
