"""Starts the real `signorini serve` (the binary named by $SIGNORINI_BIN, default
target/debug/signorini of the repository) on 127.0.0.1 ports, with a temporary store and a
loopback zenoh peer, and stops it after the tests."""

import os
import pathlib
import re
import socket
import subprocess
import threading

import pytest

from signorini import Client

REPO = pathlib.Path(__file__).resolve().parents[3]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """`signorini serve` with the shared `token` (or none), and `extra` flags (`--tls-cert`,
    `--tokens`)."""

    def __init__(self, store: pathlib.Path, token: str | None, extra: list[str] = ()):
        binary = os.environ.get("SIGNORINI_BIN", str(REPO / "target" / "debug" / "signorini"))
        if not pathlib.Path(binary).exists():
            raise RuntimeError(f"{binary} does not exist: build it (cargo build) or set SIGNORINI_BIN")
        self.zenoh = f"tcp/127.0.0.1:{free_port()}"
        env = {k: v for k, v in os.environ.items() if not k.startswith("SIGNORINI_")}
        self.proc = subprocess.Popen(
            [binary, "serve", "--grpc-addr", "127.0.0.1:0", "--http-addr", "127.0.0.1:0",
             "--store", str(store), "--zenoh-listen", self.zenoh, "--workers", "2",
             *(["--token", token] if token else []), *extra],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env,
        )
        ready = threading.Event()
        self.grpc = self.http = None

        def read() -> None:
            for line in self.proc.stdout:
                m = re.match(r"signorini serving gRPC on (\S+), HTTP on (\S+)", line)
                if m:
                    self.grpc, self.http = m.group(1), m.group(2)
                    ready.set()

        threading.Thread(target=read, daemon=True).start()
        if not ready.wait(60):
            self.stop()
            raise RuntimeError("signorini serve did not report its addresses within 60 s")

    def stop(self) -> None:
        self.proc.kill()
        self.proc.wait()


TOKEN = "python-client-test"


@pytest.fixture(scope="session")
def server(tmp_path_factory):
    s = Server(tmp_path_factory.mktemp("store") / "signorini.db", TOKEN)
    yield s
    s.stop()


@pytest.fixture
def client(server):
    with Client(server.grpc, token=TOKEN, zenoh_connect=server.zenoh) as c:
        yield c
