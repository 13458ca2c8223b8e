"""The Python client against the real service: typed and file submits, a watched job whose
streamed energy equals the stored result bit for bit (over zenoh and over gRPC), a cancel, and a
bad spec raising SpecError with the field's name, a study's runs, pause/resume bit for bit and
extend."""

import pathlib
import time
import uuid

import grpc
import numpy as np
import pytest

from signorini import Client, SignoriniError, SpecError, spec_pb2, state_name
from conftest import REPO, TOKEN

BALL = REPO / "examples" / "bouncing_ball.toml"


def typed_ball(t_end: float = 2.0) -> spec_pb2.JobSpec:
    """The bouncing ball of examples/bouncing_ball.toml as a typed message."""
    return spec_pb2.JobSpec(
        name="typed ball",
        model=spec_pb2.ModelSpec(
            bouncing_ball=spec_pb2.BouncingBall(mass=1.0, gravity=9.81, q0=1.0, v0=0.0, restitution=0.9)
        ),
        integrator=spec_pb2.IntegratorSpec(moreau_jean=spec_pb2.MoreauJean(theta=0.5)),
        time=spec_pb2.TimeSpec(h=0.005, t_end=t_end),
    )


def test_typed_submit_runs_the_ball_and_keeps_the_energy_identity(client):
    job = client.submit(typed_ball())
    assert client.wait(job, timeout=60).state == 3  # JOB_STATE_SUCCEEDED
    r = client.result(job)
    assert r.state == "succeeded"
    steps = round(2.0 / 0.005)
    assert r["step"][-1] == steps and len(r["t"]) == steps + 1
    # Moreau–Jean θ = ½ on a linear model: the energy balance closes at round-off at every step.
    assert np.max(np.abs(r["balance_residual"])) < 1e-12
    # Gravity is an external force: its work is m g (q0 − q), with q the gap of contact 0.
    assert np.allclose(r["work_ext_total"], 9.81 * (1.0 - r["gap_0"]), rtol=0, atol=1e-12)
    assert r["energy"][0] == 0.0 and r.summary["energy_final"] == r["energy"][-1]
    assert r.summary["steps"] == steps


def test_file_and_dict_submits_give_the_same_result(client):
    a = client.submit(BALL)
    b = client.submit({**__import__("tomllib").loads(BALL.read_text()), "name": "dict ball"})
    for j in (a, b):
        client.wait(j, timeout=120)
    ra, rb = client.result(a, columns=["energy"]), client.result(b, columns=["energy"])
    assert np.array_equal(ra["energy"], rb["energy"])
    assert set(ra.columns) == {"step", "t", "energy"}


@pytest.mark.parametrize("via", ["zenoh", "grpc"])
def test_watched_energy_equals_the_stored_result_bit_for_bit(client, via):
    job_id = f"py-watch-{via}-{uuid.uuid4().hex[:8]}"
    if via == "zenoh":
        watch = client.watch(job_id, via=via)  # subscribed before the job exists
        client.submit(BALL, id=job_id)
    else:
        client.submit(BALL, id=job_id)
        watch = client.watch(job_id, via=via)  # replays the stored frames, then live
    streamed: dict[int, float] = {}
    states = []
    for frame in watch:
        if frame.kind == "energy":
            streamed.update(zip(frame.step.tolist(), frame.columns["energy"].tolist()))
        elif frame.kind == "status":
            states.append(frame.state)
    assert states[-1] == "succeeded"
    r = client.result(job_id)
    stored = dict(zip(r["step"].tolist(), r["energy"].tolist()))
    assert len(streamed) == len(stored) == 2001
    # bit for bit: compare the float64 bit patterns
    keys = sorted(stored)
    a = np.array([streamed[k] for k in keys]).view(np.uint64)
    b = np.array([stored[k] for k in keys]).view(np.uint64)
    assert np.array_equal(a, b)


def test_cancel_stops_a_long_job(client):
    spec = typed_ball(t_end=1.0e5)  # 2·10⁷ steps: far longer than the test
    spec.output.every = 1000
    job = client.submit(spec)
    client.cancel(job)
    assert client.wait(job, timeout=60).state == 5  # JOB_STATE_CANCELLED


def test_a_bad_spec_raises_spec_error_naming_the_field(client):
    spec = __import__("tomllib").loads(BALL.read_text())
    spec["model"]["restitution"] = 1.5
    with pytest.raises(SpecError) as e:
        client.submit(spec)
    assert e.value.field == "model.restitution"
    assert "1.5" in str(e.value) or "[0, 1]" in str(e.value)


def test_submit_without_the_token_is_refused(server):
    with Client(server.grpc) as anonymous:
        with pytest.raises(SignoriniError) as e:
            anonymous.submit(BALL)
    assert e.value.code.name == "UNAUTHENTICATED"


def test_committed_stubs_equal_freshly_generated_ones(tmp_path):
    import sys

    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
    from generate_stubs import generate

    generate(tmp_path)
    committed = pathlib.Path(__file__).resolve().parents[1] / "src" / "signorini" / "v1"
    for fresh in sorted((tmp_path / "signorini" / "v1").glob("*.py")):
        assert fresh.read_text() == (committed / fresh.name).read_text(), (
            f"{fresh.name} is stale: run python clients/python/generate_stubs.py"
        )


def test_server_reflection_lists_the_service_and_its_messages(server):
    import grpc
    from google.protobuf.descriptor_pool import DescriptorPool
    from grpc_reflection.v1alpha.proto_reflection_descriptor_database import (
        ProtoReflectionDescriptorDatabase,
    )

    with grpc.insecure_channel(server.grpc) as channel:
        db = ProtoReflectionDescriptorDatabase(channel)
        services = db.get_services()
        assert "signorini.v1.Simulation" in services and "grpc.health.v1.Health" in services
        simulation = DescriptorPool(db).FindServiceByName("signorini.v1.Simulation")
        methods = {m.name for m in simulation.methods}
        assert {"SubmitJob", "GetJob", "WatchJob", "GetResult", "Capabilities"} <= methods
        submit = simulation.methods_by_name["SubmitJob"]
        assert "typed" in submit.input_type.fields_by_name


def test_results_stream_in_pieces_cut_on_the_server_and_jobs_page_and_delete(client):
    job = client.submit(typed_ball(t_end=20.0))  # 4000 steps
    client.wait(job, timeout=60)
    whole = client.result(job)
    assert len(whole["step"]) == 4001 and not whole.partial
    cut = client.result(job, columns=["energy"], every=10, from_step=1000, to_step=2000)
    assert set(cut.columns) == {"step", "t", "energy"}
    assert cut["step"][0] == 1000 and cut["step"][-1] == 2000 and len(cut["step"]) == 101
    np.testing.assert_array_equal(cut["energy"], whole["energy"][1000:2001:10])
    ids = [s.id for s in client.jobs(state="succeeded", page_size=2)]
    assert job in ids and len(ids) == len(set(ids))
    client.delete(job)
    assert job not in [s.id for s in client.jobs()]
    with pytest.raises(SignoriniError) as e:
        client.status(job)
    assert e.value.code.name == "NOT_FOUND"


def test_a_study_runs_as_child_jobs_and_reports_its_orders(client):
    study = __import__("tomllib").loads((REPO / "examples" / "study_dep_bar.toml").read_text())
    job = client.submit(study)
    assert client.wait(job, timeout=180).state == 3  # JOB_STATE_SUCCEEDED
    children = client.children(job)
    assert len(children) == 12 and all(c.state == 3 for c in children)
    assert client.children(children[0].id) == []
    assert client.status(children[0].id).parent == job and not client.status(job).HasField("parent")
    r = client.result(job)
    assert r.summary["kind"] == "study" and r.summary["runs"] == 12
    orders = {o["scheme"]: o["order"] for o in r.summary["orders"]}
    # docs/study.md: WFEM first order, Moreau–Jean θ = ½ ≈ 0.71 on this study.
    assert abs(orders["wfem"] - 1.0) < 0.01 and abs(orders["moreau_jean"] - 0.707) < 0.01


def test_pause_and_resume_equal_an_uninterrupted_run_and_extend_continues_it(client):
    spec = {"model": {"scene": "bouncing_ball", "restitution": 0.8},
            "time": {"h": 1e-6, "steps": 10_000_000}, "output": {"every": 10_000}}
    job = client.submit(spec)
    deadline = time.monotonic() + 60
    while client.status(job).progress.step == 0:
        assert time.monotonic() < deadline, "the job did not start"
        time.sleep(0.01)
    paused = client.pause(job)
    assert state_name(paused) == "paused" and 0 < paused.progress.step < 10_000_000
    assert state_name(client.status(job)) == "paused"
    assert state_name(client.resume(job)) in ("queued", "running")
    with pytest.raises(SignoriniError) as e:
        client.resume(job)  # no longer paused
    assert e.value.code == grpc.StatusCode.FAILED_PRECONDITION
    assert state_name(client.wait(job, timeout=120)) == "succeeded"
    whole = client.submit(spec)
    assert state_name(client.wait(whole, timeout=120)) == "succeeded"
    a, b = client.result(job), client.result(whole)
    assert a.columns.keys() == b.columns.keys() and "energy" in a.columns
    for column in a.columns:
        assert np.array_equal(a[column], b[column]), column
    for key in ("energy_final", "work_contact_total", "max_abs_balance_residual", "impacts"):
        assert a.summary[key] == b.summary[key], key

    longer = client.extend(job, 10.5, id="extended")
    assert longer == "extended"
    status = client.wait(longer, timeout=120)
    assert state_name(status) == "succeeded" and status.progress.step == 10_500_000
    assert client.status(longer).extends == job
    r = client.result(longer)
    assert r.summary["extends"] == job and r["step"][0] > 10_000_000
