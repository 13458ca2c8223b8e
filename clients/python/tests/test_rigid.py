"""A `rigid_bodies` job through the CLI and the service: `signorini run` with
`output.vtk = true` writes VTK files that VTK's own reader (the `vtk` wheel, not our code) opens,
with every body's surface at the pose steps.csv records and one vertex per contact of the index
set; and the Python client reads the service's rigid result (poses and the `contacts` table)
equal to what the CLI writes, bit for bit."""

import csv
import json
import os
import pathlib
import subprocess
import xml.etree.ElementTree as ET

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

from conftest import REPO

# A box thrown spinning onto a floor next to a ball (tests of crates/signorini-collision).
SPEC = {
    "name": "box and ball",
    "model": {
        "scene": "rigid_bodies",
        "contact": {"friction": 0.4, "restitution": 0.3, "margin": 1e-6},
        "bodies": [
            {"name": "cube", "shape": {"kind": "box", "half_extents": [0.1, 0.1, 0.1]},
             "density": 500.0, "position": [0.0, 0.0, 0.3],
             "velocity": [1.0, 0.2, 0.0], "angular_velocity": [0.5, 1.0, 3.0]},
            {"name": "ball", "shape": {"kind": "sphere", "radius": 0.1}, "density": 800.0,
             "position": [0.5, 0.0, 0.1], "velocity": [-1.0, 0.0, 0.0]},
            {"name": "floor", "shape": {"kind": "half_space", "normal": [0.0, 0.0, 1.0]}},
        ],
    },
    "integrator": {"scheme": "moreau_jean"},
    "time": {"h": 1e-3, "steps": 400},
    "output": {"every": 20, "contacts": True, "vtk": True},
}
# Points of each surface: the box's 8 corners, the sphere's 2 poles and 11 rings of 24, the
# floor's square.
POINTS = {"cube": 8, "ball": 2 + 11 * 24, "floor": 4}


def binary() -> str:
    return os.environ.get("SIGNORINI_BIN", str(REPO / "target" / "debug" / "signorini"))


def cli_run(tmp_path: pathlib.Path) -> pathlib.Path:
    spec = tmp_path / "rigid.json"
    spec.write_text(json.dumps(SPEC))
    out = tmp_path / "out"
    subprocess.run([binary(), "run", str(spec), "--out", str(out), "--quiet"], check=True)
    return out


def read_csv(path: pathlib.Path) -> dict[str, np.ndarray]:
    with open(path) as f:
        rows = list(csv.reader(f))
    return {c: np.array([float(r[i]) for r in rows[1:]]) for i, c in enumerate(rows[0])}


def collection(pvd: pathlib.Path) -> list[tuple[float, pathlib.Path]]:
    root = ET.parse(pvd).getroot()
    return [(float(d.get("timestep")), pvd.parent / d.get("file")) for d in root.iter("DataSet")]


def read_vtp(path: pathlib.Path):
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


def test_vtk_reads_every_recorded_step_with_the_poses_of_steps_csv(tmp_path):
    out = cli_run(tmp_path)
    steps = read_csv(out / "steps.csv")
    contacts = read_csv(out / "contacts.csv")
    bodies = collection(out / "vtk" / "bodies.pvd")
    assert [t for t, _ in bodies] == list(steps["t"])
    names = [b["name"] for b in SPEC["model"]["bodies"]]
    for k, (t, path) in enumerate(bodies):
        data = read_vtp(path)
        assert data.GetNumberOfPoints() == sum(POINTS.values())
        # 6 box faces, 24 × 12 sphere faces, 1 square.
        assert data.GetNumberOfPolys() == 6 + 24 * 12 + 1
        points = vtk_to_numpy(data.GetPoints().GetData())
        body = vtk_to_numpy(data.GetCellData().GetArray("body"))
        assert list(np.bincount(body)) == [6, 24 * 12, 1]
        # The mean of the box's corners is its centre, where steps.csv puts it; the sphere's
        # points lie at its radius from the recorded centre.
        first = 0
        for n in names:
            mine = points[first:first + POINTS[n]]
            first += POINTS[n]
            centre = np.array([steps[f"{n}_{c}"][k] for c in "xyz"])
            if n == "cube":
                assert np.allclose(mine.mean(axis=0), centre, rtol=0, atol=1e-12)
            if n == "ball":
                assert np.allclose(np.linalg.norm(mine - centre, axis=1), 0.1, rtol=0, atol=1e-12)
    # One vertex per contact of each step's index set, as many as steps.csv's `contacts`.
    series = collection(out / "vtk" / "contacts.pvd")
    assert [t for t, _ in series] == list(steps["t"])
    touched = 0
    for k, (t, path) in enumerate(series):
        data = read_vtp(path)
        step = steps["step"][k]
        rows = contacts["step"] == step
        assert data.GetNumberOfPoints() == rows.sum()
        if step > 0:
            assert data.GetNumberOfPoints() == steps["contacts"][k]
        if rows.sum():
            touched += 1
            force = vtk_to_numpy(data.GetPointData().GetArray("force"))
            assert np.allclose(force[:, 2], contacts["pz"][rows] / SPEC["time"]["h"], rtol=1e-15, atol=0)
            at = vtk_to_numpy(data.GetPoints().GetData())
            assert np.array_equal(at[:, 0], contacts["x"][rows])
    assert touched >= len(series) // 2


def test_the_client_reads_a_rigid_result_as_the_cli_writes_it(client, tmp_path):
    out = cli_run(tmp_path)
    steps = read_csv(out / "steps.csv")
    contacts = read_csv(out / "contacts.csv")
    job = client.submit(SPEC)
    client.wait(job, timeout=120)
    r = client.result(job)
    assert r.state == "succeeded"
    assert set(steps) == set(r.columns)
    for c in steps:
        assert np.array_equal(r[c], steps[c]), c
    table = r.tables["contacts"]
    assert set(table) == set(contacts)
    for c in contacts:
        assert np.array_equal(table[c], contacts[c]), c
    # Each contact's impulse lies in Coulomb's cone of μ = 0.4.
    assert len(table["p_n"]) > 0 and np.all(table["p_n"] >= 0)
    assert np.all(np.hypot(table["p_t1"], table["p_t2"]) <= 0.4 * table["p_n"] * (1 + 1e-9) + 1e-15)
