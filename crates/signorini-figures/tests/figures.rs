//! The figures of whole jobs, run by the core and drawn by [`render`]: well-formed SVG with axes,
//! curves and labels for the modal and forced-response analyses, and the `energy` and
//! `residuals` figures every time-integration job returns.

use signorini_core::job::{Job, run};
use signorini_core::observer::{Observer, StepRecord};
use signorini_core::spec::JobSpec;
use signorini_figures::render;
use std::ops::ControlFlow;

/// Records nothing.
struct Nothing;

impl Observer for Nothing {
    fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }
}

/// Threads granted to a job: two, so the analyses take their parallel path.
const THREADS: usize = 2;

fn job(text: &str) -> Job {
    Job::from_spec(&toml::from_str::<JobSpec>(text).expect("toml")).expect("valid job")
}

/// Minimal XML well-formedness: balanced tags, quoted attributes, no raw `&` or `<` in text.
/// Returns the element names in document order.
fn xml_elements(doc: &str) -> Vec<String> {
    let mut stack: Vec<String> = Vec::new();
    let mut names = Vec::new();
    let mut rest = doc;
    while let Some(i) = rest.find('<') {
        let text = &rest[..i];
        for (j, _) in text.match_indices('&') {
            let ent = &text[j..];
            assert!(
                ["&amp;", "&lt;", "&gt;", "&quot;", "&apos;", "&#"]
                    .iter()
                    .any(|e| ent.starts_with(e)),
                "raw & in text: {}",
                &ent[..ent.len().min(20)]
            );
        }
        let end = rest[i..].find('>').expect("unclosed tag") + i;
        let tag = &rest[i + 1..end];
        assert!(!tag.contains('<'), "'<' inside a tag: {tag}");
        if let Some(name) = tag.strip_prefix('/') {
            assert_eq!(
                stack.pop().as_deref(),
                Some(name.trim()),
                "mismatched </{name}>"
            );
        } else if !tag.starts_with('?') && !tag.starts_with('!') {
            let name: String = tag
                .chars()
                .take_while(|c| !c.is_whitespace() && *c != '/')
                .collect();
            assert_eq!(
                tag.matches('"').count() % 2,
                0,
                "unquoted attribute in <{tag}>"
            );
            names.push(name.clone());
            if !tag.ends_with('/') {
                stack.push(name);
            }
        }
        rest = &rest[end + 1..];
    }
    assert!(stack.is_empty(), "unclosed elements {stack:?}");
    assert_eq!(names.first().map(String::as_str), Some("svg"));
    names
}

#[test]
fn modal_job_figures_are_the_backbone_and_one_orbit_per_gap_in_well_formed_svg() {
    let spec = "name = \"modes\"\n[analysis]\nkind = \"nonsmooth_modes\"\ncells = 20\ngaps = [1e-3, 0.0, -1e-3]\nmax_period_steps = 80\nphases = 1\nstability_periods = 50\n";
    let out = run(&job(spec), THREADS, &mut Nothing).expect("run");
    let figures = render(&out.charts);
    // Figures: the backbone and one orbit per gap, well-formed, with axes, curves and labels.
    let names: Vec<&str> = figures.iter().map(|f| f.name.as_str()).collect();
    assert!(
        names.contains(&"backbone")
            && names.iter().filter(|n| n.starts_with("orbit_")).count() == 3,
        "{names:?}"
    );
    for f in &figures {
        let el = xml_elements(&f.svg);
        assert!(
            el.iter().filter(|e| *e == "text").count() >= 10,
            "{}: axis labels",
            f.name
        );
        if f.name.starts_with("orbit_") {
            // Space–time colour map: one cell per (x, t) block.
            assert!(
                el.iter().filter(|e| *e == "rect").count() > 100,
                "{}: colour map",
                f.name
            );
        } else {
            assert!(
                el.iter()
                    .any(|e| e == "line" || e == "path" || e == "polyline"),
                "{}: curves",
                f.name
            );
        }
        if let Some(dir) = std::env::var_os("WFEM_FIGURES") {
            std::fs::write(
                std::path::Path::new(&dir).join(format!("{}.svg", f.name)),
                &f.svg,
            )
            .unwrap();
        }
    }
    let backbone = &figures.iter().find(|f| f.name == "backbone").unwrap().svg;
    assert!(
        backbone.contains("ω / ω₁") && backbone.contains("4/3"),
        "axis label and asymptote"
    );
}

#[test]
fn forced_response_job_figure_is_well_formed_svg() {
    let spec = "name = \"forced\"\n[analysis]\nkind = \"forced_response\"\ncells = 20\ngap = 1e-3\nexcitation = \"force\"\namplitude = 2e-3\nomegas = [0.9, 1.1, 1.3, 1.5]\ndamping = [0.02, 0.1]\ntransient_periods = 40\naverage_periods = 10\n";
    let out = run(&job(spec), THREADS, &mut Nothing).expect("run");
    let figures = render(&out.charts);
    for f in &figures {
        let el = xml_elements(&f.svg);
        assert!(el.iter().filter(|e| *e == "text").count() >= 10);
        if let Some(dir) = std::env::var_os("WFEM_FIGURES") {
            std::fs::write(
                std::path::Path::new(&dir).join(format!("{}.svg", f.name)),
                &f.svg,
            )
            .unwrap();
        }
    }
}

/// Every time-integration job (linear schemes, SOI2, WFEM) returns `energy.svg` and
/// `residuals.svg`, well-formed, with one curve and one legend entry per plotted column it has;
/// an analysis returns neither.
#[test]
fn time_integration_jobs_return_energy_and_residual_figures() {
    let cases = [
        (
            include_str!("../../../examples/bouncing_ball.toml"),
            &[
                "energy",
                "kinetic",
                "strain",
                "Σ work_ext",
                "Σ work_contact",
            ][..],
            &["balance_residual"][..],
        ),
        (
            include_str!("../../../examples/bar_ns_generalized_alpha.toml"),
            &["algorithmic energy H", "Σ work_damping"][..],
            &["balance_residual"][..],
        ),
        (
            include_str!("../../../examples/slider_crank_hht.toml"),
            &["potential", "Σ work_damping"][..],
            &["position constraint g", "velocity constraint"][..],
        ),
        (
            include_str!("../../../examples/wfem_dep_bar.toml"),
            &["energy", "Σ work_ext"][..],
            &["balance_residual"][..],
        ),
    ];
    for (spec, energy_labels, residual_labels) in cases {
        let out = run(&job(spec), THREADS, &mut Nothing).expect("run");
        let figures = render(&out.charts);
        let names: Vec<&str> = figures.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["energy", "residuals"], "{spec}");
        for (f, labels) in figures.iter().zip([energy_labels, residual_labels]) {
            let el = xml_elements(&f.svg);
            let curves = el.iter().filter(|e| *e == "polyline").count();
            assert!(curves >= labels.len(), "{}: {curves} curves", f.name);
            for label in labels {
                assert!(
                    f.svg.contains(&format!(">{label}</text>")),
                    "{}: {label}",
                    f.name
                );
            }
        }
    }
    let spec = include_str!("../../../examples/nonsmooth_modes.toml");
    let out = run(&job(spec), THREADS, &mut Nothing).expect("run");
    let figures = render(&out.charts);
    assert!(
        figures
            .iter()
            .all(|f| f.name != "energy" && f.name != "residuals")
    );
}

/// Issue 30: a user's own model (`lagrangian`) gets the figures that matter for it: the energy
/// with Σ work_friction (1.3 J of a 6 J loss was missing), a `residuals` figure that is never
/// empty (its `energy_error`, the measure of a nonlinear scheme; nonlinear Moreau–Jean had
/// none, and ns_generalized_alpha without joints drew only exact zeros), and default figures of
/// its probed coordinates, gaps and impulses, one curve and legend entry per column.
#[test]
fn user_models_get_friction_work_energy_error_coordinates_gaps_and_impulses() {
    let cases = [
        (
            include_str!("../../../examples/rocking_block_friction.toml"),
            &["Σ work_friction", "potential", "Σ work_contact"][..],
            &["q_0", "q_1", "q_2"][..],
            &["p_0", "pt_0", "p_1", "pt_1"][..],
        ),
        (
            include_str!("../../../examples/rocking_block_ns_generalized_alpha.toml"),
            &["potential", "Σ work_contact"][..],
            &["q_1", "q_2"][..],
            &["p_0", "p_1"][..],
        ),
    ];
    for (text, energy_labels, probes, impulses) in cases {
        let mut spec: toml::Value = toml::from_str(text).expect("toml");
        spec["time"]["t_end"] = toml::Value::Float(0.6);
        let out = run(
            &job(&toml::to_string(&spec).expect("TOML")),
            THREADS,
            &mut Nothing,
        )
        .expect("run");
        let figures = render(&out.charts);
        let names: Vec<&str> = figures.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(
            names,
            ["energy", "residuals", "coordinates", "gaps", "impulses"],
            "{text}"
        );
        let labels_of = |name: &str, labels: &[&str]| {
            let f = figures.iter().find(|f| f.name == name).expect(name);
            let curves = xml_elements(&f.svg)
                .iter()
                .filter(|e| *e == "polyline")
                .count();
            assert!(curves >= labels.len(), "{name}: {curves} curves");
            for label in labels {
                assert!(
                    f.svg.contains(&format!(">{label}</text>")),
                    "{name}: {label}"
                );
            }
        };
        labels_of("energy", energy_labels);
        // The label without ": exactly 0 at every step": the curve has finite points.
        labels_of("residuals", &["energy_error (ΔE − works)"]);
        labels_of("coordinates", probes);
        labels_of("gaps", &["gap_0", "gap_1"]);
        labels_of("impulses", impulses);
    }
    // A built-in scene keeps its two figures (see above): the motion figures are a user
    // model's.
}
