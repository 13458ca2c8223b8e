//! Typed specs of the arms added to the proto run over gRPC: a nonsmooth generalized-α job (chain)
//! and a generalized-α-SOI2 job (the Jay–Negrut test problem, with its exact solution, full
//! Newton). Each is also submitted in the JSON spelling; both runs must give bit-identical
//! results, so the typed message reaches the same `JobSpec` as serde does.

mod common;

use common::{Options, TestServer, submit_json, wait_terminal};
use serde_json::Value;
use signorini::proto::v1 as pb;
use signorini::proto::v1::simulation_client::SimulationClient;
use tonic::transport::Channel;

fn spec(
    model: pb::model_spec::Scene,
    scheme: pb::integrator_spec::Scheme,
    time: pb::TimeSpec,
) -> pb::JobSpec {
    pb::JobSpec {
        name: Some("typed".into()),
        model: Some(pb::ModelSpec { scene: Some(model) }),
        integrator: Some(pb::IntegratorSpec {
            scheme: Some(scheme),
        }),
        time: Some(time),
        contact_solver: None,
        output: Some(pb::OutputSpec {
            every: Some(1),
            probes: vec![0, 1],
            ..Default::default()
        }),
        analysis: None,
    }
}

async fn run_typed(
    client: &mut SimulationClient<Channel>,
    id: &str,
    spec: pb::JobSpec,
) -> (Value, pb::JobResult) {
    let req = pb::SubmitJobRequest {
        spec: Some(pb::submit_job_request::Spec::Typed(spec)),
        id: Some(id.into()),
    };
    let got = client
        .submit_job(req)
        .await
        .expect("typed SubmitJob")
        .into_inner()
        .id;
    assert_eq!(got, id);
    finish(client, id).await
}

async fn finish(client: &mut SimulationClient<Channel>, id: &str) -> (Value, pb::JobResult) {
    let fin = wait_terminal(client, id).await;
    assert_eq!(fin.state, pb::JobState::Succeeded as i32, "{id}: {fin:?}");
    let r = client
        .get_result(pb::GetResultRequest {
            id: id.into(),
            ..Default::default()
        })
        .await
        .expect("GetResult")
        .into_inner();
    (serde_json::from_str(&r.summary_json).expect("summary"), r)
}

fn assert_same_run(a: &pb::JobResult, b: &pb::JobResult) {
    assert_eq!(a.columns, b.columns);
    assert_eq!(a.step, b.step);
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.t), bits(&b.t));
    for (x, y) in a.series.iter().zip(&b.series) {
        assert_eq!(x.column, y.column);
        assert_eq!(bits(&x.values), bits(&y.values), "column {}", x.column);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn typed_alpha_family_and_soi2_specs_run_over_grpc() {
    use pb::integrator_spec::Scheme;
    use pb::model_spec::Scene;
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let mut client = server.grpc().await;

    // Nonsmooth generalized-α (Acary 2016 (25)–(27)), ρ∞ = 0.8, on a three-mass chain hitting a wall.
    let alpha = spec(
        Scene::Chain(pb::ChainModel {
            positions: vec![0.1, 0.15, 0.2],
            ..Default::default()
        }),
        Scheme::NsGeneralizedAlpha(pb::NsAlpha {
            rho_inf: Some(0.8),
            ..Default::default()
        }),
        pb::TimeSpec {
            h: Some(1e-3),
            t_end: Some(1.0),
            ..Default::default()
        },
    );
    let (summary, typed) = run_typed(&mut client, "typed-alpha", alpha).await;
    assert_eq!(summary["scheme"], "ns_generalized_alpha", "{summary}");
    assert_eq!(summary["steps"], 1000, "{summary}");
    let json = r#"{"name":"typed","model":{"scene":"chain","positions":[0.1,0.15,0.2]},
        "integrator":{"scheme":"ns_generalized_alpha","rho_inf":0.8},"time":{"h":0.001,"t_end":1.0},
        "output":{"every":1,"probes":[0,1]}}"#;
    submit_json(&mut client, json.into(), Some("json-alpha"))
        .await
        .expect("JSON submit");
    let (_, from_json) = finish(&mut client, "json-alpha").await;
    assert_same_run(&typed, &from_json);

    // Generalized-α-SOI2 (Jay & Negrut 2008 (13)) on their test problem (15), variable steps
    // with the adjusting formulas, as in the paper's Fig. 1 setting.
    let soi2 = spec(
        Scene::JayNegrutTest(pb::JayNegrutTest::default()),
        Scheme::Soi2GeneralizedAlpha(pb::Soi2GeneralizedAlpha {
            rho_inf: Some(0.2),
            start: pb::Soi2Start::A0 as i32,
            newton: pb::Soi2Newton::Full as i32,
            ..Default::default()
        }),
        pb::TimeSpec {
            h: Some(0.015625),
            t_end: Some(1.0),
            pattern: vec![1.0 / 3.0, 2.0 / 3.0],
            adjust: Some(true),
            steps: None,
        },
    );
    let (summary, typed) = run_typed(&mut client, "typed-soi2", soi2).await;
    assert_eq!(summary["scheme"], "soi2_generalized_alpha", "{summary}");
    // Full Newton reached the job: one Jacobian per Newton iteration.
    assert_eq!(summary["newton"], "full", "{summary}");
    assert_eq!(
        summary["newton_jacobians_total"], summary["newton_iterations_total"],
        "{summary}"
    );
    // The exact solution is known: the global errors at t_end are small (second order, h = 2⁻⁶).
    for var in ["y", "z", "a", "lambda", "psi"] {
        let e = summary["errors"][var]
            .as_f64()
            .unwrap_or_else(|| panic!("errors.{var}: {summary}"));
        assert!(e.is_finite() && e < 1e-2, "errors.{var} = {e}");
    }
    let json = format!(
        r#"{{"name":"typed","model":{{"scene":"jay_negrut_test"}},
        "integrator":{{"scheme":"soi2_generalized_alpha","rho_inf":0.2,"start":"a0","newton":"full"}},
        "time":{{"h":0.015625,"t_end":1.0,"pattern":[{:?},{:?}],"adjust":true}},
        "output":{{"every":1,"probes":[0,1]}}}}"#,
        1.0f64 / 3.0,
        2.0f64 / 3.0
    );
    submit_json(&mut client, json, Some("json-soi2"))
        .await
        .expect("JSON submit");
    let (json_summary, from_json) = finish(&mut client, "json-soi2").await;
    assert_same_run(&typed, &from_json);
    assert_eq!(json_summary["errors"], summary["errors"]);
    assert_eq!(json_summary["newton"], "full", "{json_summary}");
}
