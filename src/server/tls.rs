//! TLS for both listeners: `serve --tls-cert FILE --tls-key FILE` (PEM: the certificate chain,
//! leaf first, and its private key in PKCS#8, PKCS#1 or SEC1). Both the gRPC and the HTTP port
//! then speak TLS only (rustls, with the ring provider): a plain-text connection fails its
//! handshake and is closed. gRPC negotiates `h2` by ALPN; HTTP offers `h2` and `http/1.1`.
//!
//! The HTTP side is a [`TlsListener`] for `axum::serve`: a task accepts TCP connections and runs
//! each handshake on a task of its own, bounded by [`HANDSHAKE_TIMEOUT`], so a client that
//! connects and says nothing holds up no one.

use anyhow::{Context, Result, anyhow};
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio_rustls::TlsAcceptor;
use tokio_rustls::server::TlsStream;

/// Longest a TLS handshake may take before its connection is dropped.
pub const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(10);

/// Handshaken connections waiting for `axum::serve` to take them.
const READY_BACKLOG: usize = 64;

/// The server's certificate and key, checked once, for both listeners.
#[derive(Clone)]
pub struct ServerTls {
    /// For the HTTP listener.
    acceptor: TlsAcceptor,
    /// For tonic's own TLS (the same certificate and key).
    identity: tonic::transport::Identity,
}

/// The process-wide rustls provider: ring (the only one built; tonic's server configuration
/// asks for the process default).
fn provider() -> Arc<rustls::crypto::CryptoProvider> {
    let ring = Arc::new(rustls::crypto::ring::default_provider());
    // Already installed (a second server in one process): keep the first.
    let _ = ring.as_ref().clone().install_default();
    ring
}

impl ServerTls {
    /// Reads and checks `cert` (PEM certificate chain, leaf first) and `key` (PEM private key):
    /// each file is named in the error when it holds no certificate, no key, or a key that does
    /// not match the certificate.
    pub fn load(cert: &Path, key: &Path) -> Result<ServerTls> {
        let cert_pem = std::fs::read(cert)
            .with_context(|| format!("reading --tls-cert {}", cert.display()))?;
        let key_pem =
            std::fs::read(key).with_context(|| format!("reading --tls-key {}", key.display()))?;
        let chain = CertificateDer::pem_slice_iter(&cert_pem)
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| anyhow!("--tls-cert {}: {e}", cert.display()))?;
        if chain.is_empty() {
            return Err(anyhow!(
                "--tls-cert {}: no PEM certificate in it",
                cert.display()
            ));
        }
        let private = PrivateKeyDer::from_pem_slice(&key_pem).map_err(|e| {
            anyhow!(
                "--tls-key {}: no PEM private key in it ({e})",
                key.display()
            )
        })?;
        let mut config = rustls::ServerConfig::builder_with_provider(provider())
            .with_safe_default_protocol_versions()
            .context("TLS protocol versions")?
            .with_no_client_auth()
            .with_single_cert(chain, private)
            .with_context(|| {
                format!(
                    "--tls-key {} does not go with --tls-cert {}",
                    key.display(),
                    cert.display()
                )
            })?;
        config.alpn_protocols = vec![b"h2".to_vec(), b"http/1.1".to_vec()];
        Ok(ServerTls {
            acceptor: TlsAcceptor::from(Arc::new(config)),
            identity: tonic::transport::Identity::from_pem(cert_pem, key_pem),
        })
    }

    /// tonic's TLS configuration for the gRPC listener.
    pub fn grpc(&self) -> tonic::transport::ServerTlsConfig {
        tonic::transport::ServerTlsConfig::new()
            .identity(self.identity.clone())
            .timeout(HANDSHAKE_TIMEOUT)
    }

    /// The HTTP listener over `tcp`.
    pub fn listener(&self, tcp: TcpListener) -> std::io::Result<TlsListener> {
        TlsListener::new(tcp, self.acceptor.clone())
    }
}

/// A TCP listener whose connections come out TLS-handshaken (see the module documentation).
pub struct TlsListener {
    ready: mpsc::Receiver<(TlsStream<TcpStream>, SocketAddr)>,
    local: SocketAddr,
    accepting: tokio::task::JoinHandle<()>,
}

impl TlsListener {
    fn new(tcp: TcpListener, acceptor: TlsAcceptor) -> std::io::Result<TlsListener> {
        let local = tcp.local_addr()?;
        let (tx, ready) = mpsc::channel(READY_BACKLOG);
        let accepting = tokio::spawn(async move {
            loop {
                let accepted = tokio::select! {
                    a = tcp.accept() => a,
                    () = tx.closed() => return,
                };
                let (stream, peer) = match accepted {
                    Ok(a) => a,
                    Err(e) => {
                        // Out of file descriptors and the like: wait a little, as axum does.
                        tracing::warn!("accepting an HTTPS connection: {e}");
                        tokio::time::sleep(Duration::from_millis(50)).await;
                        continue;
                    }
                };
                super::no_delay(&stream);
                let (acceptor, tx) = (acceptor.clone(), tx.clone());
                tokio::spawn(async move {
                    match tokio::time::timeout(HANDSHAKE_TIMEOUT, acceptor.accept(stream)).await {
                        Ok(Ok(tls)) => {
                            let _ = tx.send((tls, peer)).await;
                        }
                        Ok(Err(e)) => tracing::debug!(%peer, "TLS handshake failed: {e}"),
                        Err(_) => tracing::debug!(%peer, "TLS handshake timed out"),
                    }
                });
            }
        });
        Ok(TlsListener {
            ready,
            local,
            accepting,
        })
    }
}

impl Drop for TlsListener {
    fn drop(&mut self) {
        self.accepting.abort();
    }
}

impl axum::serve::Listener for TlsListener {
    type Io = TlsStream<TcpStream>;
    type Addr = SocketAddr;

    async fn accept(&mut self) -> (Self::Io, Self::Addr) {
        match self.ready.recv().await {
            Some(conn) => conn,
            // The accepting task is gone only when this listener is dropped.
            None => std::future::pending().await,
        }
    }

    fn local_addr(&self) -> std::io::Result<SocketAddr> {
        Ok(self.local)
    }
}
