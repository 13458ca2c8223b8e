"""The gRPC client of the Signorini service, with live frames over zenoh (or gRPC) and results
as numpy arrays."""

from __future__ import annotations

import json
import pathlib
import queue
import threading
import time
import tomllib
from dataclasses import dataclass, field
from typing import Any, Iterator, Mapping

import grpc
import numpy as np

from .v1 import service_pb2, service_pb2_grpc, spec_pb2

#: Job states by their proto value, spelled as the HTTP API spells them.
STATES = {
    service_pb2.JOB_STATE_UNSPECIFIED: "unspecified",
    service_pb2.JOB_STATE_QUEUED: "queued",
    service_pb2.JOB_STATE_RUNNING: "running",
    service_pb2.JOB_STATE_SUCCEEDED: "succeeded",
    service_pb2.JOB_STATE_FAILED: "failed",
    service_pb2.JOB_STATE_CANCELLED: "cancelled",
    service_pb2.JOB_STATE_PAUSED: "paused",
}
TERMINAL = {"succeeded", "failed", "cancelled"}


class SignoriniError(Exception):
    """A call the service refused or could not answer."""

    def __init__(self, message: str, code: grpc.StatusCode | None = None):
        super().__init__(message)
        self.code = code


class SpecError(SignoriniError):
    """A spec the service refused: `field` names the offending field (`model.restitution`)."""

    def __init__(self, field_name: str, reason: str, code: grpc.StatusCode):
        super().__init__(f"{field_name}: {reason}" if field_name else reason, code)
        self.field = field_name
        self.reason = reason


def _raise(err: grpc.RpcError) -> None:
    """Re-raises a gRPC error as a SpecError (INVALID_ARGUMENT) or a SignoriniError."""
    code = err.code()
    details = err.details() or ""
    if code == grpc.StatusCode.INVALID_ARGUMENT:
        trailing = dict(err.trailing_metadata() or ())
        field_name = trailing.get("x-error-field", "")
        reason = details
        if field_name and details.startswith(f"{field_name}: "):
            reason = details[len(field_name) + 2 :]
        raise SpecError(field_name, reason, code) from None
    raise SignoriniError(f"{code.name}: {details}", code) from None


def state_name(status: service_pb2.JobStatus) -> str:
    """`succeeded`, `running`, … of a JobStatus."""
    return STATES.get(status.state, "unspecified")


def _spec_request(spec: Any) -> service_pb2.SubmitJobRequest:
    """A typed JobSpec is sent typed; a dict, or a .toml/.json file, as the service's JSON spelling."""
    if isinstance(spec, spec_pb2.JobSpec):
        return service_pb2.SubmitJobRequest(typed=spec)
    if isinstance(spec, (str, pathlib.Path)):
        path = pathlib.Path(spec)
        text = path.read_text(encoding="utf-8")
        if path.suffix == ".toml":
            spec = tomllib.loads(text)
        elif path.suffix == ".json":
            spec = json.loads(text)
        else:
            raise ValueError(f"{path}: a spec file ends in .toml or .json")
    if isinstance(spec, Mapping):
        return service_pb2.SubmitJobRequest(json=json.dumps(spec, allow_nan=False))
    raise TypeError(f"a spec is a JobSpec message, a dict or a .toml/.json path, not {type(spec).__name__}")


@dataclass
class Frame:
    """One frame of a job's stream: a status, or several recorded steps (`energy` or `state`)."""

    kind: str
    status: service_pb2.JobStatus | None = None
    seq: int = 0
    step: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.uint64))
    t: np.ndarray = field(default_factory=lambda: np.empty(0))
    columns: dict[str, np.ndarray] = field(default_factory=dict)
    last: bool = False

    @property
    def state(self) -> str | None:
        """The job state of a status frame."""
        return state_name(self.status) if self.status is not None else None

    @staticmethod
    def of_steps(kind: str, f: service_pb2.StepFrame) -> "Frame":
        names = list(f.columns)
        values = np.asarray(f.values, dtype=np.float64).reshape(len(f.step), len(names))
        return Frame(
            kind=kind,
            seq=f.seq,
            step=np.asarray(f.step, dtype=np.uint64),
            t=np.asarray(f.t, dtype=np.float64),
            columns={c: values[:, i].copy() for i, c in enumerate(names)},
            last=f.last,
        )


@dataclass
class Result:
    """A finished job: `columns` maps every recorded column (with `step` and `t`) to a numpy
    array; `summary` is summary.json; `tables` maps a table name to its columns; `figures` a
    figure name to its SVG text; `partial` marks the rows a failed or cancelled run recorded."""

    id: str
    state: str
    summary: dict
    columns: dict[str, np.ndarray]
    tables: dict[str, dict[str, np.ndarray]]
    figures: dict[str, str]
    status: service_pb2.JobStatus
    partial: bool = False

    def __getitem__(self, column: str) -> np.ndarray:
        return self.columns[column]


class Watch:
    """The frames of one job, from the moment this object exists until the job ends.

    Over zenoh it subscribes on construction, so `w = client.watch(id)` before
    `client.submit(spec, id=id)` sees every frame; over gRPC the job must exist, and its stored
    frames are replayed before the live ones, so nothing is missed either. Iterate it (it ends
    after the terminal status) or use it as a context manager; `via` is `"zenoh"` or `"grpc"`."""

    def __init__(self, client: "Client", job_id: str, via: str, timeout: float | None):
        self._queue: queue.Queue = queue.Queue()
        self._timeout = timeout
        self._closers: list = []
        self.job_id = job_id
        self.via = via
        if via == "zenoh":
            self._open_zenoh(client, job_id)
        elif via == "grpc":
            self._open_grpc(client, job_id)
        else:
            raise ValueError(f"via: 'zenoh' or 'grpc', not {via!r}")

    def _open_zenoh(self, client: "Client", job_id: str) -> None:
        session = client._zenoh_session()
        prefix = f"signorini/v1/jobs/{job_id}/"

        def on_sample(sample) -> None:
            key = str(sample.key_expr)
            payload = sample.payload.to_bytes()
            kind = key[len(prefix) :] if key.startswith(prefix) else ""
            if kind == "status":
                self._queue.put(Frame("status", status=service_pb2.JobStatus.FromString(payload)))
            elif kind in ("energy", "state"):
                self._queue.put(Frame.of_steps(kind, service_pb2.StepFrame.FromString(payload)))

        sub = session.declare_subscriber(prefix + "*", on_sample)
        self._closers.append(sub.undeclare)
        # A job that ended before the subscription sends nothing more: ask for its status.
        for reply in session.get(prefix + "status", timeout=5.0):
            if reply.ok is not None:
                status = service_pb2.JobStatus.FromString(reply.ok.payload.to_bytes())
                if state_name(status) in TERMINAL:
                    self._queue.put(Frame("status", status=status))

    def _open_grpc(self, client: "Client", job_id: str) -> None:
        # from_seq = 0: the job's stored frames first, then the live ones (no gap).
        call = client._stub.WatchJob(
            service_pb2.WatchJobRequest(id=job_id, from_seq=0), metadata=client._metadata
        )
        self._closers.append(call.cancel)
        started = threading.Event()

        def pump() -> None:
            started.set()
            try:
                for w in call:
                    which = w.WhichOneof("frame")
                    if which == "status":
                        self._queue.put(Frame("status", status=w.status))
                    elif which in ("energy", "state"):
                        self._queue.put(Frame.of_steps(which, getattr(w, which)))
            except grpc.RpcError as e:
                if e.code() != grpc.StatusCode.CANCELLED:
                    self._queue.put(e)
            self._queue.put(None)

        threading.Thread(target=pump, daemon=True).start()
        started.wait()

    def __iter__(self) -> Iterator[Frame]:
        try:
            while True:
                try:
                    item = self._queue.get(timeout=self._timeout)
                except queue.Empty:
                    raise SignoriniError(f"no frame of job {self.job_id} for {self._timeout} s") from None
                if item is None:
                    return
                if isinstance(item, grpc.RpcError):
                    _raise(item)
                yield item
                if item.kind == "status" and item.state in TERMINAL:
                    return
        finally:
            self.close()

    def close(self) -> None:
        while self._closers:
            self._closers.pop()()

    def __enter__(self) -> "Watch":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class Client:
    """A connection to `signorini serve`.

    >>> c = Client("127.0.0.1:50051")
    >>> job = c.submit("examples/bouncing_ball.toml")
    >>> c.wait(job)
    >>> r = c.result(job); r["energy"]        # numpy array

    `token` is a bearer token sent with every call: the shared token of `serve --token` (needed
    by the calls that change jobs), or a per-client token of `serve --tokens FILE` (a read token
    for reads, a write token for both); `ca` the CA certificate (a PEM file's path, or its
    bytes) that signed the certificate of a server started with `--tls-cert`: the connection is
    then TLS and the server must present a certificate it signed for the host of `target`;
    `zenoh_connect` the service's zenoh endpoint (e.g. "tcp/127.0.0.1:7447") for `watch`.
    """

    def __init__(
        self,
        target: str = "127.0.0.1:50051",
        *,
        token: str | None = None,
        ca: str | pathlib.Path | bytes | None = None,
        zenoh_connect: str | list[str] | None = None,
        max_message_mb: int = 1024,
    ):
        size = max_message_mb * 1024 * 1024
        options = [
            ("grpc.max_receive_message_length", size),
            ("grpc.max_send_message_length", size),
        ]
        if ca is None:
            self._channel = grpc.insecure_channel(target, options=options)
        else:
            pem = ca if isinstance(ca, bytes) else pathlib.Path(ca).read_bytes()
            credentials = grpc.ssl_channel_credentials(root_certificates=pem)
            self._channel = grpc.secure_channel(target, credentials, options=options)
        self._stub = service_pb2_grpc.SimulationStub(self._channel)
        self._metadata = (("authorization", f"Bearer {token}"),) if token else ()
        if isinstance(zenoh_connect, str):
            zenoh_connect = [zenoh_connect]
        self._zenoh_connect = zenoh_connect
        self._zenoh = None

    def _call(self, method: str, request):
        try:
            return getattr(self._stub, method)(request, metadata=self._metadata)
        except grpc.RpcError as e:
            _raise(e)

    def submit(self, spec: Any, *, id: str | None = None) -> str:
        """Queues a job and returns its id. `spec`: a `signorini.v1.spec_pb2.JobSpec` (sent
        typed), a dict, or the path of a .toml/.json spec. Raises SpecError naming the field
        of a bad spec."""
        request = _spec_request(spec)
        if id is not None:
            request.id = id
        return self._call("SubmitJob", request).id

    def status(self, job_id: str) -> service_pb2.JobStatus:
        """The job's status (`state_name(status)` spells its state)."""
        return self._call("GetJob", service_pb2.GetJobRequest(id=job_id))

    def cancel(self, job_id: str) -> service_pb2.JobStatus:
        """Cancels a queued, running or paused job."""
        return self._call("CancelJob", service_pb2.CancelJobRequest(id=job_id))

    def pause(self, job_id: str) -> service_pb2.JobStatus:
        """Pauses a job: a running one writes a checkpoint after its next step and parks, a
        queued one parks at once; either is left "paused" until `resume`."""
        return self._call("PauseJob", service_pb2.PauseJobRequest(id=job_id))

    def resume(self, job_id: str) -> service_pb2.JobStatus:
        """Queues a paused job again; it continues from its checkpoint, bit for bit as if it
        had never stopped."""
        return self._call("ResumeJob", service_pb2.ResumeJobRequest(id=job_id))

    def extend(self, job_id: str, t_end: float, *, id: str | None = None) -> str:
        """A new job continuing the succeeded job `job_id` from its final state to `t_end`
        (after its own end); returns the new job's id. Its result holds the rows after the
        first job's end, its summary the whole run's energy ledger, and `status(new).extends`
        names `job_id`."""
        request = service_pb2.ExtendJobRequest(id=job_id, t_end=t_end)
        if id is not None:
            request.new_id = id
        return self._call("ExtendJob", request).id

    def jobs(self, state: str | None = None, page_size: int = 100) -> Iterator[service_pb2.JobStatus]:
        """The service's jobs, newest first (only those in `state`, e.g. "running"), fetched
        one page at a time."""
        wanted = 0
        if state is not None:
            names = {v: k for k, v in STATES.items()}
            if state not in names:
                raise ValueError(f"state: one of {sorted(names)}, not {state!r}")
            wanted = names[state]
        token = ""
        while True:
            page = self._call(
                "ListJobs",
                service_pb2.ListJobsRequest(limit=page_size, page_token=token, state=wanted),
            )
            yield from page.jobs
            token = page.next_page_token
            if not token:
                return

    def children(self, job_id: str) -> list[service_pb2.JobStatus]:
        """The child jobs of a study's parent job (a spec with [study]), in study order: the
        reference run first if the study has one, then one per run; empty for any other job."""
        return list(self._call("ListChildren", service_pb2.ListChildrenRequest(id=job_id)).jobs)

    def capabilities(self) -> service_pb2.CapabilitiesResponse:
        """Models, integrators, contact solvers, analyses and their parameters."""
        return self._call("Capabilities", service_pb2.CapabilitiesRequest())

    def wait(self, job_id: str, timeout: float | None = None, poll: float = 0.05) -> service_pb2.JobStatus:
        """Polls until the job ends; returns its final status."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            status = self.status(job_id)
            if state_name(status) in TERMINAL:
                return status
            if deadline is not None and time.monotonic() > deadline:
                raise SignoriniError(f"job {job_id} still {state_name(status)} after {timeout} s")
            time.sleep(poll)

    def result(
        self,
        job_id: str,
        columns: list[str] | None = None,
        every: int = 0,
        from_step: int | None = None,
        to_step: int | None = None,
    ) -> Result:
        """The result of a finished job, as numpy arrays, received with StreamResult in
        messages of about 1 MiB (any size of result, under every default message limit) and
        written into arrays allocated once. A failed or cancelled job's recorded rows come with
        `partial = True`. `columns`, `every`, `from_step`, `to_step` cut the rows on the server."""
        request = service_pb2.GetResultRequest(id=job_id, columns=columns or [], every=every)
        if from_step is not None:
            request.from_step = from_step
        if to_step is not None:
            request.to_step = to_step
        try:
            stream = self._stub.StreamResult(request, metadata=self._metadata)
            header = None
            figures: dict[str, str] = {}
            cols: dict[str, np.ndarray] = {}
            for chunk in stream:
                part = chunk.WhichOneof("part")
                if part == "header":
                    header = chunk.header
                    n = header.rows
                    cols = {"step": np.empty(n, dtype=np.uint64), "t": np.empty(n)}
                    names = list(header.columns)
                    for c in names:
                        cols[c] = np.empty(n)
                elif part == "figure":
                    figures[chunk.figure.name] = chunk.figure.svg
                elif part == "rows" and header is not None:
                    rows = chunk.rows
                    a, k = rows.first_row, len(rows.step)
                    cols["step"][a : a + k] = rows.step
                    cols["t"][a : a + k] = rows.t
                    values = np.asarray(rows.values, dtype=np.float64).reshape(k, len(names))
                    for i, c in enumerate(names):
                        cols[c][a : a + k] = values[:, i]
        except grpc.RpcError as e:
            _raise(e)
        if header is None:
            raise SignoriniError(f"job {job_id}: the result stream sent no header")
        tables = {
            tb.name: {
                c: np.asarray([row.values[i] for row in tb.rows], dtype=np.float64)
                for i, c in enumerate(tb.columns)
            }
            for tb in header.tables
        }
        return Result(
            id=header.id,
            state=state_name(header.status),
            summary=json.loads(header.summary_json) if header.summary_json else {},
            columns=cols,
            tables=tables,
            figures=figures,
            status=header.status,
            partial=header.partial,
        )

    def delete(self, job_id: str) -> None:
        """Removes a finished job and its result."""
        self._call("DeleteJob", service_pb2.DeleteJobRequest(id=job_id))

    def watch(self, job_id: str, *, via: str = "auto", timeout: float | None = 60.0) -> Watch:
        """The job's live frames (see `Watch`). `via="auto"` uses zenoh when eclipse-zenoh is
        installed and `zenoh_connect` was given, gRPC WatchJob otherwise."""
        if via == "auto":
            via = "zenoh" if self._zenoh_connect and _has_zenoh() else "grpc"
        return Watch(self, job_id, via, timeout)

    def _zenoh_session(self):
        if self._zenoh is None:
            if not self._zenoh_connect:
                raise SignoriniError("watch via zenoh needs Client(..., zenoh_connect='tcp/HOST:7447')")
            import zenoh

            config = zenoh.Config()
            config.insert_json5("mode", json.dumps("peer"))
            config.insert_json5("connect/endpoints", json.dumps(self._zenoh_connect))
            config.insert_json5("listen/endpoints", json.dumps([]))
            config.insert_json5("scouting/multicast/enabled", "false")
            self._zenoh = zenoh.open(config)
        return self._zenoh

    def close(self) -> None:
        """Closes the gRPC channel and the zenoh session."""
        if self._zenoh is not None:
            self._zenoh.close()
            self._zenoh = None
        self._channel.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _has_zenoh() -> bool:
    try:
        import zenoh  # noqa: F401
    except ImportError:
        return False
    return True
