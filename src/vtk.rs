//! The ParaView files of a rigid run (`output.vtk = true`): per recorded step, the
//! bodies' surfaces at their poses and the contact points with their impulses, as VTK XML
//! PolyData (`.vtp`), and one `.pvd` collection per series giving each file its time.
//!
//! `DIR/vtk/bodies.pvd` lists `bodies_STEP.vtp`: every body's surface ([`surface`]: spheres,
//! capsules and cylinders tessellated, boxes, convex hulls, half-spaces as a square) moved to the
//! body's pose x + R(q) p, one cell datum `body` (its index in `model.bodies`) per face.
//! `DIR/vtk/contacts.pvd` lists `contacts_STEP.vtp`: one vertex per contact of that step's index
//! set (the `contacts` table), with point data `normal`, `impulse` (P, world), `force` (P / h)
//! and `p_n`. ParaView opens either `.pvd` and plays it in time.
//!
//! The files are made after the run from `steps.csv` (the poses) and the `contacts` table, so a
//! resumed run writes the bodies of every recorded step (the contacts of the records after its
//! checkpoint: the table is not in the checkpoint).

use anyhow::{Context, Result, anyhow};
use signorini_collision::surface::{Surface, scene_surfaces};
use signorini_core::outcome::Table;
use signorini_core::rigid::RigidScene;
use std::fmt::Write as _;
use std::fs;
use std::path::Path;

/// The folder of the VTK files in a run's output directory.
pub const VTK_DIR: &str = "vtk";

/// A recorded step series: the columns (`step`, `t`, then the run's) and the rows.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StepSeries {
    /// Column names, `step` and `t` first.
    pub columns: Vec<String>,
    /// One row per recorded step.
    pub rows: Vec<Vec<f64>>,
}

impl StepSeries {
    /// Reads a `steps.csv` as the CLI writes it (header, then numbers).
    pub fn read_csv(path: &Path) -> Result<Self> {
        let text =
            fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let mut lines = text.lines();
        let header = lines
            .next()
            .ok_or_else(|| anyhow!("{} is empty", path.display()))?;
        let columns: Vec<String> = header.split(',').map(str::to_string).collect();
        let rows = lines
            .enumerate()
            .map(|(i, line)| {
                line.split(',')
                    .map(|v| v.parse::<f64>())
                    .collect::<Result<Vec<f64>, _>>()
                    .with_context(|| format!("{} line {}", path.display(), i + 2))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self { columns, rows })
    }

    fn index(&self, name: &str) -> Result<usize> {
        self.columns
            .iter()
            .position(|c| c == name)
            .ok_or_else(|| anyhow!("steps.csv has no column `{name}`"))
    }
}

/// Writes `dir/vtk/` for a rigid run of `scene` with step `h` from its recorded `steps` and its
/// `contacts` table (none: the contact series is left out). Files of an earlier run there are
/// replaced; the two `.pvd` are written last.
pub fn write_rigid_vtk(
    dir: &Path,
    scene: &RigidScene,
    h: f64,
    steps: &StepSeries,
    contacts: Option<&Table>,
) -> Result<()> {
    let out = dir.join(VTK_DIR);
    fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    remove_old_files(&out)?;
    let surfaces = scene_surfaces(scene)?;
    let (i_step, i_t) = (steps.index("step")?, steps.index("t")?);
    let pose_columns: Vec<usize> = scene
        .names
        .iter()
        .flat_map(|n| ["x", "y", "z", "qw", "qx", "qy", "qz"].map(|c| format!("{n}_{c}")))
        .map(|c| steps.index(&c))
        .collect::<Result<_>>()?;

    let mut bodies_pvd = Vec::with_capacity(steps.rows.len());
    let mut contacts_pvd = Vec::with_capacity(steps.rows.len());
    for row in &steps.rows {
        let (step, t) = (row[i_step] as u64, row[i_t]);
        let poses: Vec<[f64; 7]> = pose_columns
            .chunks_exact(7)
            .map(|c| std::array::from_fn(|k| row[c[k]]))
            .collect();
        let name = format!("bodies_{step:09}.vtp");
        write_file(&out.join(&name), &bodies_vtp(&surfaces, &poses))?;
        bodies_pvd.push((t, name));
        if let Some(table) = contacts {
            let name = format!("contacts_{step:09}.vtp");
            write_file(&out.join(&name), &contacts_vtp(table, step, h)?)?;
            contacts_pvd.push((t, name));
        }
    }
    if contacts.is_some() {
        write_file(&out.join("contacts.pvd"), &collection(&contacts_pvd))?;
    }
    write_file(&out.join("bodies.pvd"), &collection(&bodies_pvd))
}

/// Removes the `.vtp` and `.pvd` files of an earlier run (nothing else in the folder).
fn remove_old_files(out: &Path) -> Result<()> {
    for entry in fs::read_dir(out).with_context(|| format!("reading {}", out.display()))? {
        let path = entry?.path();
        if path
            .extension()
            .is_some_and(|x| x == "vtp" || x == "pvd" || x == "partial")
        {
            fs::remove_file(&path).with_context(|| format!("removing {}", path.display()))?;
        }
    }
    Ok(())
}

fn write_file(path: &Path, text: &str) -> Result<()> {
    crate::output::write_atomic(path, text)
}

/// R(q) p for a unit quaternion q = (w, x, y, z): p + 2w (u × p) + 2 u × (u × p), u = (x, y, z).
fn rotate(q: [f64; 4], p: [f64; 3]) -> [f64; 3] {
    let u = [q[1], q[2], q[3]];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let c1 = cross(u, p);
    let c2 = cross(u, c1);
    [0, 1, 2].map(|i| p[i] + 2.0 * q[0] * c1[i] + 2.0 * c2[i])
}

/// One PolyData piece: points, optional verts or polys, point and cell data (already XML).
struct Piece<'a> {
    points: &'a [[f64; 3]],
    cells: &'a [Vec<u32>],
    /// `Verts` or `Polys`.
    kind: &'static str,
    point_data: String,
    cell_data: String,
}

fn piece(p: &Piece<'_>) -> String {
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<PolyData>\n",
    );
    let (verts, polys) = if p.kind == "Verts" {
        (p.cells.len(), 0)
    } else {
        (0, p.cells.len())
    };
    let _ = writeln!(
        s,
        "<Piece NumberOfPoints=\"{}\" NumberOfVerts=\"{verts}\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"{polys}\">",
        p.points.len()
    );
    s.push_str("<Points>\n");
    s.push_str(&data_array(
        "Float64",
        "Points",
        3,
        p.points.iter().flatten().copied(),
    ));
    s.push_str("</Points>\n");
    let _ = writeln!(s, "<PointData>\n{}</PointData>", p.point_data);
    let _ = writeln!(s, "<CellData>\n{}</CellData>", p.cell_data);
    let _ = writeln!(s, "<{}>", p.kind);
    s.push_str(&data_array(
        "Int64",
        "connectivity",
        1,
        p.cells.iter().flatten().map(|&i| f64::from(i)),
    ));
    let offsets = p.cells.iter().scan(0u32, |end, c| {
        *end += c.len() as u32;
        Some(f64::from(*end))
    });
    s.push_str(&data_array("Int64", "offsets", 1, offsets));
    let _ = writeln!(s, "</{}>", p.kind);
    s.push_str("</Piece>\n</PolyData>\n</VTKFile>\n");
    s
}

/// A `DataArray` in ASCII; Float64 values are written so that they read back exactly.
fn data_array(
    ty: &str,
    name: &str,
    components: usize,
    values: impl Iterator<Item = f64>,
) -> String {
    let mut s = format!(
        "<DataArray type=\"{ty}\" Name=\"{name}\" NumberOfComponents=\"{components}\" format=\"ascii\">\n"
    );
    for v in values {
        if ty == "Float64" {
            let _ = write!(s, "{v:?} ");
        } else {
            let _ = write!(s, "{} ", v as i64);
        }
    }
    s.push_str("\n</DataArray>\n");
    s
}

/// The bodies at their poses ([x, y, z, qw, qx, qy, qz] per body) as one piece of polygons.
fn bodies_vtp(surfaces: &[Surface], poses: &[[f64; 7]]) -> String {
    let mut points = Vec::new();
    let mut faces = Vec::new();
    let mut body = Vec::new();
    for (b, (s, pose)) in surfaces.iter().zip(poses).enumerate() {
        let first = points.len() as u32;
        let q = [pose[3], pose[4], pose[5], pose[6]];
        points.extend(s.points.iter().map(|&p| {
            let r = rotate(q, p);
            [pose[0] + r[0], pose[1] + r[1], pose[2] + r[2]]
        }));
        for f in &s.faces {
            faces.push(f.iter().map(|i| first + i).collect());
            body.push(b as f64);
        }
    }
    piece(&Piece {
        points: &points,
        cells: &faces,
        kind: "Polys",
        point_data: String::new(),
        cell_data: data_array("Int32", "body", 1, body.into_iter()),
    })
}

/// The contacts of `step` in the `contacts` table, one vertex each, with their normals,
/// impulses and forces.
fn contacts_vtp(table: &Table, step: u64, h: f64) -> Result<String> {
    let col = |name: &str| {
        table
            .columns
            .iter()
            .position(|c| c == name)
            .ok_or_else(|| anyhow!("the contacts table has no column `{name}`"))
    };
    let i_step = col("step")?;
    let point = [col("x")?, col("y")?, col("z")?];
    let normal = [col("nx")?, col("ny")?, col("nz")?];
    let impulse = [col("px")?, col("py")?, col("pz")?];
    let p_n = col("p_n")?;
    let rows: Vec<&Vec<f64>> = table
        .rows
        .iter()
        .filter(|r| r[i_step] == step as f64)
        .collect();
    let pick = |cols: [usize; 3]| -> Vec<f64> {
        rows.iter()
            .flat_map(|r| cols.map(|c| r[c]))
            .collect::<Vec<_>>()
    };
    let points: Vec<[f64; 3]> = rows.iter().map(|r| point.map(|c| r[c])).collect();
    let verts: Vec<Vec<u32>> = (0..rows.len() as u32).map(|i| vec![i]).collect();
    let mut point_data = data_array("Float64", "normal", 3, pick(normal).into_iter());
    point_data += &data_array("Float64", "impulse", 3, pick(impulse).into_iter());
    point_data += &data_array(
        "Float64",
        "force",
        3,
        pick(impulse).into_iter().map(|p| p / h),
    );
    point_data += &data_array("Float64", "p_n", 1, rows.iter().map(|r| r[p_n]));
    Ok(piece(&Piece {
        points: &points,
        cells: &verts,
        kind: "Verts",
        point_data,
        cell_data: String::new(),
    }))
}

/// A `.pvd` collection: each file with its time.
fn collection(files: &[(f64, String)]) -> String {
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n<Collection>\n",
    );
    for (t, file) in files {
        let _ = writeln!(
            s,
            "<DataSet timestep=\"{t:?}\" group=\"\" part=\"0\" file=\"{file}\"/>"
        );
    }
    s.push_str("</Collection>\n</VTKFile>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use signorini_core::spec::{JobSpec, ModelSpec};

    fn scene() -> RigidScene {
        let spec: JobSpec = serde_json::from_value(serde_json::json!({
            "model": {
                "scene": "rigid_bodies",
                "bodies": [
                    { "name": "floor", "shape": { "kind": "half_space", "normal": [0.0, 0.0, 1.0] } },
                    { "name": "cube", "shape": { "kind": "box", "half_extents": [0.1, 0.2, 0.3] },
                      "density": 1.0, "position": [1.0, 0.0, 0.3] }
                ]
            },
            "integrator": { "scheme": "moreau_jean" },
            "time": { "h": 0.5, "steps": 2 }
        }))
        .unwrap();
        let Some(ModelSpec::RigidBodies(r)) = &spec.model else {
            unreachable!()
        };
        r.validate().unwrap()
    }

    /// The numbers of a `DataArray` named `name` in a file.
    fn array(text: &str, name: &str) -> Vec<f64> {
        let start = text.find(&format!("Name=\"{name}\"")).unwrap();
        let body = &text[start..];
        let open = body.find('>').unwrap() + 1;
        let close = body.find("</DataArray>").unwrap();
        body[open..close]
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect()
    }

    #[test]
    fn the_files_hold_each_recorded_pose_and_contact_with_its_time() {
        let dir = tempfile::tempdir().unwrap();
        let names = ["floor", "cube"];
        let mut columns = vec!["step".to_string(), "t".to_string()];
        for n in names {
            for c in ["x", "y", "z", "qw", "qx", "qy", "qz"] {
                columns.push(format!("{n}_{c}"));
            }
        }
        // The cube turned by 90° about z at step 2: q = (cos 45°, 0, 0, sin 45°).
        let c = std::f64::consts::FRAC_1_SQRT_2;
        let floor = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
        let rows = vec![
            [
                vec![0.0, 0.0],
                floor.to_vec(),
                vec![1.0, 0.0, 0.3, 1.0, 0.0, 0.0, 0.0],
            ]
            .concat(),
            [
                vec![2.0, 1.0],
                floor.to_vec(),
                vec![2.0, 0.0, 0.3, c, 0.0, 0.0, c],
            ]
            .concat(),
        ];
        let steps = StepSeries { columns, rows };
        let contacts = Table {
            name: "contacts".into(),
            columns: signorini_core::rigid::CONTACT_COLUMNS
                .iter()
                .map(|c| c.to_string())
                .collect(),
            rows: vec![
                vec![
                    2.0, 1.0, 0.0, 1.0, 1.9, 0.1, 0.0, 0.0, 0.0, 1.0, 0.0, 0.25, 0.0, 0.0, 0.0,
                    0.0, 0.25,
                ],
                vec![
                    2.0, 1.0, 0.0, 1.0, 2.1, -0.1, 0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.0, 0.0, 0.0,
                    0.0, 0.5,
                ],
            ],
        };
        write_rigid_vtk(dir.path(), &scene(), 0.5, &steps, Some(&contacts)).unwrap();
        let vtk = dir.path().join(VTK_DIR);
        let pvd = fs::read_to_string(vtk.join("bodies.pvd")).unwrap();
        assert!(
            pvd.contains("timestep=\"0.0\" group=\"\" part=\"0\" file=\"bodies_000000000.vtp\"")
        );
        assert!(
            pvd.contains("timestep=\"1.0\" group=\"\" part=\"0\" file=\"bodies_000000002.vtp\"")
        );
        let bodies = fs::read_to_string(vtk.join("bodies_000000002.vtp")).unwrap();
        // The floor's square (4 points) then the box's 8 corners.
        assert!(bodies.contains("NumberOfPoints=\"12\"") && bodies.contains("NumberOfPolys=\"7\""));
        let points = array(&bodies, "Points");
        // Corner 7 of the box, (+a, +b, +c) = (0.1, 0.2, 0.3), turned by 90° about z is
        // (−0.2, 0.1, 0.3), at (2, 0, 0.3).
        let corner = &points[3 * (4 + 7)..3 * (4 + 8)];
        let expect = [1.8, 0.1, 0.6];
        assert!(
            (0..3).all(|i| (corner[i] - expect[i]).abs() < 1e-14),
            "{corner:?}"
        );
        assert_eq!(array(&bodies, "body"), [0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]);
        // Step 0 had no contact; step 2 has the table's two, forces P / h.
        let none = fs::read_to_string(vtk.join("contacts_000000000.vtp")).unwrap();
        assert!(none.contains("NumberOfPoints=\"0\""));
        let two = fs::read_to_string(vtk.join("contacts_000000002.vtp")).unwrap();
        assert!(two.contains("NumberOfPoints=\"2\"") && two.contains("NumberOfVerts=\"2\""));
        assert_eq!(array(&two, "force"), [0.0, 0.0, 0.5, 0.0, 0.0, 1.0]);
        assert_eq!(array(&two, "Points"), [1.9, 0.1, 0.0, 2.1, -0.1, 0.0]);
        assert_eq!(array(&two, "offsets"), [1.0, 2.0]);
    }
}
