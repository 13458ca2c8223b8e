"""The Python client against a server with TLS (`serve --tls-cert/--tls-key`, a CA and a server
certificate made here with the openssl command) and per-client tokens (`serve --tokens FILE`):
`Client(..., ca=...)` works over TLS and is refused by a server its CA did not sign; a read token
reads and cannot submit, no token cannot even read."""

import hashlib
import pathlib
import subprocess

import pytest

from signorini import Client, SignoriniError, state_name
from conftest import Server

READ, WRITE = "py-read-token", "py-write-token"
BALL = {"model": {"scene": "bouncing_ball"}, "time": {"h": 0.01, "steps": 50}}


def openssl(*args: str, cwd: pathlib.Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


def authority(dir: pathlib.Path, name: str) -> None:
    """NAME.key and NAME.pem: a self-signed certificate authority."""
    openssl("req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
            "-keyout", f"{name}.key", "-out", f"{name}.pem", "-days", "2", "-subj", f"/CN={name}",
            "-addext", "basicConstraints=critical,CA:TRUE", "-addext", "keyUsage=keyCertSign",
            cwd=dir)


@pytest.fixture(scope="module")
def secured(tmp_path_factory):
    """A TLS server with read and write tokens; yields it with the directory of the PEM files."""
    d = tmp_path_factory.mktemp("pki")
    authority(d, "ca")
    authority(d, "other")
    openssl("req", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
            "-keyout", "server.key", "-out", "server.csr", "-subj", "/CN=localhost", cwd=d)
    (d / "ext.cnf").write_text("subjectAltName=DNS:localhost,IP:127.0.0.1\nextendedKeyUsage=serverAuth\n")
    openssl("x509", "-req", "-in", "server.csr", "-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial",
            "-out", "server.pem", "-days", "2", "-extfile", "ext.cnf", cwd=d)
    digest = lambda t: hashlib.sha256(t.encode()).hexdigest()
    (d / "tokens.toml").write_text(
        f'[[token]]\nname = "notebook"\nscope = "read"\nsha256 = "{digest(READ)}"\n\n'
        f'[[token]]\nname = "pipeline"\nscope = "write"\nsha256 = "{digest(WRITE)}"\n'
    )
    server = Server(d / "store.db", None, ["--tls-cert", str(d / "server.pem"), "--tls-key",
                                           str(d / "server.key"), "--tokens", str(d / "tokens.toml")])
    yield server, d
    server.stop()


def test_tls_with_the_ca_works_and_a_read_token_reads_but_cannot_submit(secured):
    server, d = secured
    with Client(server.grpc, token=WRITE, ca=d / "ca.pem") as writer:
        job = writer.submit(BALL)
        assert state_name(writer.wait(job, timeout=60)) == "succeeded"
    with Client(server.grpc, token=READ, ca=(d / "ca.pem").read_bytes()) as reader:
        r = reader.result(job)
        assert r.state == "succeeded" and len(r["t"]) == 51
        assert job in [s.id for s in reader.jobs()]
        with pytest.raises(SignoriniError) as refused:
            reader.submit(BALL)
        assert refused.value.code.name == "PERMISSION_DENIED"
    with Client(server.grpc, ca=d / "ca.pem") as anonymous:
        with pytest.raises(SignoriniError) as refused:
            anonymous.status(job)
        assert refused.value.code.name == "UNAUTHENTICATED"


def test_a_client_of_another_ca_or_without_tls_is_refused(secured):
    server, d = secured
    with Client(server.grpc, token=READ, ca=d / "other.pem") as wrong:
        with pytest.raises(SignoriniError) as refused:
            wrong.capabilities()
        assert refused.value.code.name == "UNAVAILABLE"
    with Client(server.grpc, token=READ) as plain:
        with pytest.raises(SignoriniError) as refused:
            plain.capabilities()
        assert refused.value.code.name == "UNAVAILABLE"
