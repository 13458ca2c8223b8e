"""Python client of Signorini, the nonsmooth contact dynamics service.

    from signorini import Client
    with Client("127.0.0.1:50051", zenoh_connect="tcp/127.0.0.1:7447") as c:
        job = c.submit("examples/bouncing_ball.toml")
        for frame in c.watch(job):
            ...
        energy = c.result(job)["energy"]
"""

from .client import (
    STATES,
    TERMINAL,
    Client,
    Frame,
    Result,
    SignoriniError,
    SpecError,
    Watch,
    state_name,
)
from .v1 import service_pb2, spec_pb2

__all__ = [
    "STATES",
    "TERMINAL",
    "Client",
    "Frame",
    "Result",
    "SignoriniError",
    "SpecError",
    "Watch",
    "service_pb2",
    "spec_pb2",
    "state_name",
]
