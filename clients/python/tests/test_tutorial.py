"""docs/tutorial.md's service parts cannot go stale: its `curl` commands (step 4) and its Python
snippet (step 5) are taken from the page and run against a real `signorini serve` on 127.0.0.1
(ephemeral ports), in a directory holding the page's files, with this installed client. What the
page quotes must be what they print: each quoted output, cut at its `…`, must appear piece by
piece, in order, in what the command printed; the snippet must print the line its comment quotes.
(tests/tutorial.rs runs the page's `signorini` commands.)"""

import json
import re
import subprocess
import sys
import time
import urllib.request

import pytest

from conftest import REPO, Server

PAGE = (REPO / "docs" / "tutorial.md").read_text()


def blocks(markdown: str) -> list[tuple[str, str]]:
    """The fenced blocks of `markdown`, as (info string, body)."""
    return [(m.group(1).strip(), m.group(2))
            for m in re.finditer(r"^```([^\n]*)\n(.*?)^```", markdown, re.S | re.M)]


def console_commands(markdown: str) -> list[tuple[str, str]]:
    """The `$ ` commands of the page's `console` blocks, each with the output it quotes."""
    out = []
    for info, body in blocks(markdown):
        if info != "console":
            continue
        for chunk in re.split(r"^\$ ", body, flags=re.M)[1:]:
            command, _, quoted = chunk.partition("\n")
            out.append((command, quoted.rstrip("\n")))
    return out


def assert_quoted(quoted: str, printed: str, what: str) -> None:
    """Every piece of `quoted` between its `…` is in `printed`, in order."""
    at = 0
    for piece in quoted.split("…"):
        found = printed.find(piece, at)
        assert found >= 0, f"{what}: the page quotes {piece!r}, the command printed {printed!r}"
        at = found + len(piece)


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    s = Server(tmp_path_factory.mktemp("tutorial-store") / "signorini.db", None)
    yield s
    s.stop()


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("tutorial")
    for info, body in blocks(PAGE):
        if info.startswith("toml file="):
            (d / info.removeprefix("toml file=")).write_text(body)
    assert (d / "pendulum.toml").is_file()
    return d


def wait_for_end(http: str, job: str) -> dict:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        with urllib.request.urlopen(f"http://{http}/v1/jobs/{job}") as r:
            status = json.load(r)
        if status["state"] in ("succeeded", "failed", "cancelled"):
            return status
        time.sleep(0.2)
    raise AssertionError(f"job {job} did not end within 120 s")


def test_the_tutorials_curl_commands_print_what_it_quotes(service, workdir):
    commands = console_commands(PAGE)
    assert [c for c, _ in commands if c.startswith("signorini serve")], "step 4 starts the service"
    curls = [(c, q) for c, q in commands if c.startswith("curl ")]
    assert len(curls) >= 4, curls
    quoted_id = None
    for command, quoted in curls:
        command = command.replace("localhost:8080", service.http)
        if quoted_id is not None:
            command = command.replace(quoted_id, job)
            quoted = quoted.replace(quoted_id, job)
        done = subprocess.run(command, shell=True, cwd=workdir, capture_output=True, text=True,
                              timeout=120)
        assert done.returncode == 0, f"{command}: {done.stderr}"
        if quoted_id is None:
            # The submission: the page's id stands for the one the server gives.
            quoted_id = json.loads(quoted)["id"]
            job = json.loads(done.stdout)["id"]
            # The page shows the job finished, as it is a few seconds later.
            assert wait_for_end(service.http, job)["state"] == "succeeded"
            continue
        if quoted:
            assert_quoted(quoted, done.stdout, command)
    # The figure the last command saved.
    svg = (workdir / "energy.svg").read_text()
    assert svg.lstrip().startswith(("<svg", "<?xml")) and "</svg>" in svg

    # The 400 the page quotes, for the typo it shows (`thetta` in the gap).
    refusal = re.search(r"A bad spec is a 400 naming the field:\s*`([^`]+)`", PAGE)
    assert refusal, "the page quotes a refusal"
    typo = (workdir / "pendulum.toml").read_text().replace("L*sin(theta)", "L*sin(thetta)")
    request = urllib.request.Request(f"http://{service.http}/v1/jobs", data=typo.encode(),
                                     headers={"content-type": "application/toml"}, method="POST")
    with pytest.raises(urllib.error.HTTPError) as refused:
        urllib.request.urlopen(request)
    assert refused.value.code == 400
    assert json.loads(refused.value.read()) == json.loads(refusal.group(1))


def test_the_tutorials_python_prints_what_it_quotes(service, workdir):
    snippets = [body for info, body in blocks(PAGE) if info == "python"]
    assert len(snippets) == 1, snippets
    snippet = snippets[0]
    assert "127.0.0.1:50051" in snippet
    quoted = re.search(r"print\(.*\)\s*#\s*(.+)$", snippet, re.M)
    assert quoted, "the snippet quotes what it prints"
    done = subprocess.run([sys.executable, "-c", snippet.replace("127.0.0.1:50051", service.grpc)],
                          cwd=workdir, capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == quoted.group(1).strip()
