//! TLS on both listeners (`serve --tls-cert FILE --tls-key FILE`), with a certificate authority
//! and a server certificate made by the test (rcgen): HTTPS and gRPC over TLS work for a client
//! that trusts the authority (the CLI's `--ca`), plain text to either port fails, and a client
//! that trusts another authority is refused. zenoh between the server and a router speaks TLS
//! with zenoh's own configuration (`transport.link.tls`), refusing plain text and strangers.

mod common;

use common::{Options, TestServer, ball_json, wait_terminal};
use http_body_util::{BodyExt, Full};
use hyper::body::Bytes;
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, ServerName};
use signorini::proto::v1 as pb;
use signorini::proto::v1::simulation_client::SimulationClient;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use tonic::transport::{Certificate, ClientTlsConfig, Endpoint};

/// The PEM files of one test: the server's certificate and key, the authority that signed it,
/// and an authority that did not.
struct Pki {
    cert: PathBuf,
    key: PathBuf,
    ca: PathBuf,
    other_ca: PathBuf,
}

/// A certificate authority: its self-signed certificate (PEM) and what signs with it.
fn authority(name: &str) -> (String, rcgen::Issuer<'static, rcgen::KeyPair>) {
    let key = rcgen::KeyPair::generate().expect("CA key");
    let mut params = rcgen::CertificateParams::new(Vec::<String>::new()).expect("CA params");
    params.is_ca = rcgen::IsCa::Ca(rcgen::BasicConstraints::Unconstrained);
    params
        .distinguished_name
        .push(rcgen::DnType::CommonName, name);
    params.key_usages = vec![
        rcgen::KeyUsagePurpose::KeyCertSign,
        rcgen::KeyUsagePurpose::DigitalSignature,
    ];
    let cert = params.self_signed(&key).expect("CA certificate");
    (cert.pem(), rcgen::Issuer::new(params, key))
}

fn pki(dir: &Path) -> Pki {
    let (ca_pem, ca) = authority("signorini test CA");
    let (other_pem, _) = authority("another CA");
    let key = rcgen::KeyPair::generate().expect("server key");
    let mut params = rcgen::CertificateParams::new(vec!["localhost".into(), "127.0.0.1".into()])
        .expect("server params");
    params.extended_key_usages = vec![rcgen::ExtendedKeyUsagePurpose::ServerAuth];
    let cert = params.signed_by(&key, &ca).expect("server certificate");
    let pki = Pki {
        cert: dir.join("cert.pem"),
        key: dir.join("key.pem"),
        ca: dir.join("ca.pem"),
        other_ca: dir.join("other_ca.pem"),
    };
    std::fs::write(&pki.cert, cert.pem()).expect("cert.pem");
    std::fs::write(&pki.key, key.serialize_pem()).expect("key.pem");
    std::fs::write(&pki.ca, ca_pem).expect("ca.pem");
    std::fs::write(&pki.other_ca, other_pem).expect("other_ca.pem");
    pki
}

/// One HTTPS request trusting only the authority in `ca` (a PEM file): status and body, or the
/// error that stopped it (the handshake's, for a certificate the authority did not sign).
async fn https(
    addr: SocketAddr,
    method: &str,
    path: &str,
    body: &str,
    ca: &Path,
) -> Result<(u16, serde_json::Value), String> {
    let mut roots = rustls::RootCertStore::empty();
    for cert in CertificateDer::pem_file_iter(ca).expect("CA file") {
        roots.add(cert.expect("CA PEM")).expect("CA certificate");
    }
    let config = rustls::ClientConfig::builder_with_provider(Arc::new(
        rustls::crypto::ring::default_provider(),
    ))
    .with_safe_default_protocol_versions()
    .expect("TLS versions")
    .with_root_certificates(roots)
    .with_no_client_auth();
    let tcp = tokio::net::TcpStream::connect(addr)
        .await
        .map_err(|e| e.to_string())?;
    let name = ServerName::try_from("127.0.0.1").expect("server name");
    let tls = tokio_rustls::TlsConnector::from(Arc::new(config))
        .connect(name, tcp)
        .await
        .map_err(|e| format!("TLS: {e}"))?;
    let (mut sender, conn) =
        hyper::client::conn::http1::handshake(hyper_util::rt::TokioIo::new(tls))
            .await
            .map_err(|e| e.to_string())?;
    tokio::spawn(conn);
    let req = hyper::Request::builder()
        .method(method)
        .uri(path)
        .header("host", addr.to_string())
        .header("content-type", "application/json")
        .body(Full::new(Bytes::from(body.to_string())))
        .expect("request");
    let resp = sender.send_request(req).await.map_err(|e| e.to_string())?;
    let status = resp.status().as_u16();
    let bytes = resp
        .into_body()
        .collect()
        .await
        .map_err(|e| e.to_string())?
        .to_bytes();
    Ok((
        status,
        serde_json::from_slice(&bytes).unwrap_or(serde_json::Value::Null),
    ))
}

/// A gRPC client over TLS trusting the authority in `ca`.
async fn grpc_tls(
    server: &TestServer,
    ca: &Path,
) -> Result<SimulationClient<tonic::transport::Channel>, tonic::transport::Error> {
    let url = server.grpc_url.replace("http://", "https://");
    let pem = std::fs::read(ca).expect("CA file");
    let channel = Endpoint::from_shared(url)?
        .tls_config(ClientTlsConfig::new().ca_certificate(Certificate::from_pem(pem)))?
        .connect()
        .await?;
    Ok(SimulationClient::new(channel))
}

/// The CLI with `args`: exit status, stdout, stderr.
fn cli(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .args(args)
        .env_remove("SIGNORINI_SERVER")
        .env_remove("SIGNORINI_TOKEN")
        .env_remove("SIGNORINI_CA")
        .output()
        .expect("running signorini");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[tokio::test(flavor = "multi_thread")]
async fn both_ports_speak_tls_only_and_refuse_a_client_of_another_authority() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let pki = pki(tmp.path());
    let (cert, key) = (
        pki.cert.display().to_string(),
        pki.key.display().to_string(),
    );
    let server = TestServer::start_with(
        &tmp.path().join("store.db"),
        &Options::default(),
        &["--tls-cert", &cert, "--tls-key", &key],
    );

    // HTTPS: health, a submission, its result.
    let (code, health) = https(server.http, "GET", "/healthz", "", &pki.ca)
        .await
        .expect("HTTPS /healthz");
    assert_eq!((code, health["status"].as_str()), (200, Some("ok")));
    let (code, submitted) = https(
        server.http,
        "POST",
        "/v1/jobs",
        &ball_json(1e-3, 200, 1),
        &pki.ca,
    )
    .await
    .expect("HTTPS POST /v1/jobs");
    assert_eq!(code, 201, "{submitted}");
    let id = submitted["id"].as_str().expect("an id").to_string();

    // gRPC over TLS: the job's end and its result.
    let mut client = grpc_tls(&server, &pki.ca).await.expect("gRPC over TLS");
    let end = wait_terminal(&mut client, &id).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    let result = client
        .get_result(pb::GetResultRequest {
            id: id.clone(),
            ..Default::default()
        })
        .await
        .expect("GetResult over TLS")
        .into_inner();
    assert_eq!(result.step.len(), 201);
    let (code, result) = https(
        server.http,
        "GET",
        &format!("/v1/jobs/{id}/result"),
        "",
        &pki.ca,
    )
    .await
    .expect("HTTPS result");
    assert_eq!(code, 200, "{result}");
    assert_eq!(result["steps"]["step"].as_array().map(Vec::len), Some(201));

    // Plain text to either port fails.
    let plain: hyper_util::client::legacy::Client<_, Full<Bytes>> =
        hyper_util::client::legacy::Client::builder(hyper_util::rt::TokioExecutor::new())
            .build_http();
    let answer = plain
        .get(
            format!("http://{}/healthz", server.http)
                .parse()
                .expect("uri"),
        )
        .await;
    assert!(
        answer.is_err(),
        "plain HTTP was answered: {:?}",
        answer.map(|r| r.status())
    );
    let plain_grpc = async {
        let mut c = SimulationClient::connect(server.grpc_url.clone()).await?;
        c.get_job(pb::GetJobRequest { id: id.clone() })
            .await
            .map_err(|s| -> Box<dyn std::error::Error> { Box::new(s) })?;
        Ok::<_, Box<dyn std::error::Error>>(())
    };
    let answer = plain_grpc.await;
    assert!(answer.is_err(), "plain gRPC was answered");

    // A client trusting another authority is refused, over both.
    let refused = https(server.http, "GET", "/healthz", "", &pki.other_ca).await;
    let why = refused.expect_err("HTTPS with the wrong CA");
    assert!(why.starts_with("TLS:"), "{why}");
    let refused = async {
        let mut c = grpc_tls(&server, &pki.other_ca)
            .await
            .map_err(|e| e.to_string())?;
        c.get_job(pb::GetJobRequest { id: id.clone() })
            .await
            .map_err(|s| s.to_string())?;
        Ok::<_, String>(())
    }
    .await;
    assert!(refused.is_err(), "gRPC with the wrong CA was answered");

    // The CLI: `--ca` makes the connection TLS (an http:// URL is taken as https://).
    let https_url = server.grpc_url.replace("http://", "https://");
    let ca = pki.ca.display().to_string();
    for url in [&https_url, &server.grpc_url] {
        let (ok, out, err) = cli(&["status", &id, "--server", url, "--ca", &ca]);
        assert!(ok, "status over TLS with --ca ({url}): {err}");
        let status: serde_json::Value = serde_json::from_str(&out).expect("status JSON");
        assert_eq!(status["state"], "succeeded", "{out}");
    }
    let other = pki.other_ca.display().to_string();
    let (ok, _, err) = cli(&["status", &id, "--server", &https_url, "--ca", &other]);
    assert!(!ok, "the CLI trusted a server its CA did not sign");
    assert!(err.contains("connecting to"), "{err}");
    let (ok, _, err) = cli(&["status", &id, "--server", &https_url]);
    assert!(!ok);
    assert!(err.contains("--ca"), "{err}");
    let (ok, _, err) = cli(&["status", &id, "--server", &server.grpc_url]);
    assert!(!ok, "the CLI spoke plain gRPC to a TLS port");
    assert!(!err.is_empty());
}

/// A certificate without its key, or with a key that is not its own, is refused at start,
/// naming the files.
#[test]
fn serve_refuses_a_certificate_without_its_own_key() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let pki = pki(tmp.path());
    let other_key = tmp.path().join("other_key.pem");
    std::fs::write(
        &other_key,
        rcgen::KeyPair::generate().expect("key").serialize_pem(),
    )
    .expect("other_key.pem");
    let store = tmp.path().join("store.db").display().to_string();
    let serve = |extra: &[&str]| {
        let mut args = vec![
            "serve",
            "--grpc-addr",
            "127.0.0.1:0",
            "--http-addr",
            "127.0.0.1:0",
            "--store",
            store.as_str(),
            "--zenoh-listen",
            "tcp/127.0.0.1:0",
        ];
        args.extend_from_slice(extra);
        cli(&args)
    };
    let cert = pki.cert.display().to_string();
    let (ok, _, err) = serve(&["--tls-cert", &cert]);
    assert!(!ok);
    assert!(err.contains("--tls-key"), "{err}");
    let other = other_key.display().to_string();
    let (ok, _, err) = serve(&["--tls-cert", &cert, "--tls-key", &other]);
    assert!(!ok);
    assert!(
        err.contains("does not go with") && err.contains("other_key.pem"),
        "{err}"
    );
    let key = pki.key.display().to_string();
    let (ok, _, err) = serve(&["--tls-cert", &key, "--tls-key", &key]);
    assert!(!ok);
    assert!(err.contains("no PEM certificate"), "{err}");
}

/// A zenoh configuration (JSON5) of `mode` whose links trust only the authority in `ca`; with
/// `listen` (the certificate and key of a router), its TLS listener's too.
fn zenoh_tls_config(mode: &str, ca: &Path, listen: Option<&Pki>) -> String {
    let listen = listen.map_or(String::new(), |p| {
        format!(
            "listen_certificate: {:?}, listen_private_key: {:?},",
            p.cert.display().to_string(),
            p.key.display().to_string()
        )
    });
    format!(
        r#"{{ mode: "{mode}", scouting: {{ multicast: {{ enabled: false }} }},
  transport: {{ link: {{ tls: {{ root_ca_certificate: {:?}, {listen} }} }} }} }}"#,
        ca.display().to_string()
    )
}

/// zenoh over TLS between the service and a router (zenoh's own TLS configuration, the
/// `transport_tls` feature): a router listening on `tls/127.0.0.1:PORT` with the test's
/// certificate, the server connected to it with a configuration that trusts the authority, and
/// `signorini watch` as a client of the router: the watcher gets every energy frame of a job to
/// its last, with the stored rows' count. A watcher connecting in plain text (`tcp/`) to the
/// router's TLS port, or trusting another authority, reaches no server and exits 1.
#[tokio::test(flavor = "multi_thread")]
async fn zenoh_links_to_a_router_speak_tls_and_refuse_plain_text_and_another_authority() {
    let dir = tempfile::tempdir().expect("tempdir");
    let pki = pki(dir.path());
    let endpoint = format!("tls/127.0.0.1:{}", common::free_port());
    let mut router_config =
        zenoh::Config::from_json5(&zenoh_tls_config("router", &pki.ca, Some(&pki)))
            .expect("router config");
    router_config
        .insert_json5("listen/endpoints", &format!("[\"{endpoint}\"]"))
        .expect("router endpoint");
    let router = zenoh::open(router_config).await.expect("a TLS router");

    let peer = dir.path().join("peer.json5");
    std::fs::write(&peer, zenoh_tls_config("peer", &pki.ca, None)).expect("peer config");
    let opts = Options {
        workers: 1,
        zenoh_config: Some(peer),
        ..Options::default()
    };
    let server = TestServer::start_with(
        &dir.path().join("s.db"),
        &opts,
        &["--zenoh-connect", &endpoint],
    );
    let mut client = server.grpc().await;
    const STEPS: u64 = 4_000_000;
    let id = common::submit_json(&mut client, ball_json(1e-6, STEPS, 1000), Some("tls"))
        .await
        .expect("submit");
    common::wait_running(&mut client, &id, 1).await;

    let viewer = |name: &str, ca: &Path| {
        let path = dir.path().join(name);
        std::fs::write(&path, zenoh_tls_config("client", ca, None)).expect("viewer config");
        path
    };
    let (trusting, other) = (
        viewer("viewer.json5", &pki.ca),
        viewer("other.json5", &pki.other_ca),
    );
    let watch = |config: &Path, connect: &str| {
        Command::new(env!("CARGO_BIN_EXE_signorini"))
            .args(["watch", &id, "--json", "--zenoh-connect", connect])
            .arg("--zenoh-config")
            .arg(config)
            .args(["--server", &server.grpc_url])
            .output()
            .expect("signorini watch")
    };
    let plain = endpoint.replace("tls/", "tcp/");
    let (good, plain_text, stranger) = std::thread::scope(|s| {
        let good = s.spawn(|| watch(&trusting, &endpoint));
        let plain_text = s.spawn(|| watch(&trusting, &plain));
        let stranger = s.spawn(|| watch(&other, &endpoint));
        (
            good.join().expect("watch"),
            plain_text.join().expect("watch"),
            stranger.join().expect("watch"),
        )
    });
    assert!(
        good.status.success(),
        "{}",
        String::from_utf8_lossy(&good.stderr)
    );
    let text = String::from_utf8(good.stdout).expect("UTF-8");
    let energy: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).expect("a JSON line"))
        .filter(|v| v["kind"] == "energy")
        .collect();
    assert_eq!(
        energy.last().map(|v| &v["last"]),
        Some(&serde_json::Value::Bool(true))
    );
    let rows: u64 = energy
        .iter()
        .map(|v| v["step"].as_array().map_or(0, Vec::len) as u64)
        .sum();
    let first = energy[0]["step"][0].as_u64().expect("a step");
    assert_eq!(
        rows,
        (STEPS - first) / 1000 + 1,
        "every row from step {first}"
    );
    for (what, out) in [("plain text", plain_text), ("another authority", stranger)] {
        assert!(
            !out.status.success(),
            "{what}: watch reached the server: {}",
            String::from_utf8_lossy(&out.stdout)
        );
        assert!(
            !String::from_utf8_lossy(&out.stdout).contains("\"energy\""),
            "{what}: frames arrived"
        );
    }
    let end = wait_terminal(&mut client, &id).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    drop(server);
    router.close().await.expect("closing the router");
}
