"""Regenerates the protobuf/gRPC stubs in src/signorini/v1 from the repository's proto/ files.

    python clients/python/generate_stubs.py            # rewrite the committed stubs
    python clients/python/generate_stubs.py --out DIR  # write them elsewhere (the consistency test)

Needs grpcio-tools (pip install grpcio-tools): its bundled protoc, no system protoc.
"""

import argparse
import pathlib
import sys

from grpc_tools import protoc

HERE = pathlib.Path(__file__).resolve().parent
PROTO_ROOT = HERE.parent.parent / "proto"
PROTOS = ["signorini/v1/spec.proto", "signorini/v1/service.proto"]


def generate(out: pathlib.Path) -> None:
    """Writes spec_pb2.py, service_pb2.py, service_pb2_grpc.py under out/signorini/v1."""
    out.mkdir(parents=True, exist_ok=True)
    args = [
        "grpc_tools.protoc",
        f"-I{PROTO_ROOT}",
        f"--python_out={out}",
        f"--grpc_python_out={out}",
        *[str(PROTO_ROOT / p) for p in PROTOS],
    ]
    if protoc.main(args) != 0:
        raise SystemExit(f"protoc failed on {PROTOS}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=pathlib.Path, default=HERE / "src")
    generate(parser.parse_args().out)


if __name__ == "__main__":
    sys.exit(main())
