//! The surfaces of the bodies' shapes as polygon meshes in the body frame, for pictures: the VTK
//! files of a run and the live page's 3D view. Contact detection never reads them.
//!
//! Round shapes are surfaces of revolution about the body z axis, drawn with
//! [`SEGMENTS`] segments around the axis: a sphere (and a capsule's two hemispheres) with
//! [`SEGMENTS`]/2 segments from pole to pole; a cylinder with two flat caps. A convex hull is
//! parry's hull of its points, a half-space a square of half side `extent` in its boundary plane.

use parry3d_f64::math::Vector;
use signorini_core::rigid::{DetectError, RigidScene, Shape, tangent_basis};
use std::f64::consts::PI;

/// Segments around an axis of revolution.
pub const SEGMENTS: usize = 24;

/// A polygon mesh: vertices in the body frame and faces as vertex indices, counter-clockwise
/// seen from outside.
#[derive(Debug, Clone, PartialEq)]
pub struct Surface {
    /// Vertices (body frame).
    pub points: Vec<[f64; 3]>,
    /// Faces (triangles and quadrilaterals; a cylinder's caps are polygons of [`SEGMENTS`]
    /// vertices).
    pub faces: Vec<Vec<u32>>,
}

/// The surface of `shape` (body `body` of its scene, named in an error); a half-space is a
/// square of half side `extent`.
pub fn surface(body: usize, shape: &Shape, extent: f64) -> Result<Surface, DetectError> {
    Ok(match *shape {
        Shape::Sphere { radius } => revolved(&round_profile(radius, 0.0)),
        Shape::Capsule {
            radius,
            half_height,
        } => revolved(&round_profile(radius, half_height)),
        Shape::Cylinder {
            radius,
            half_height,
        } => revolved(&[
            (0.0, half_height),
            (radius, half_height),
            (radius, -half_height),
            (0.0, -half_height),
        ]),
        Shape::Box {
            half_extents: [a, b, c],
        } => {
            let points = (0..8)
                .map(|i| {
                    let s = |bit: usize, x: f64| if i & bit != 0 { x } else { -x };
                    [s(1, a), s(2, b), s(4, c)]
                })
                .collect();
            // Corner i has x > 0 when bit 1 is set, y > 0 for bit 2, z > 0 for bit 4.
            let faces = [
                [0, 2, 3, 1], // z < 0
                [4, 5, 7, 6], // z > 0
                [0, 1, 5, 4], // y < 0
                [2, 6, 7, 3], // y > 0
                [0, 4, 6, 2], // x < 0
                [1, 3, 7, 5], // x > 0
            ];
            Surface {
                points,
                faces: faces.iter().map(|f| f.to_vec()).collect(),
            }
        }
        Shape::Convex { ref points } => {
            let pts: Vec<Vector> = points
                .iter()
                .map(|p| Vector::new(p[0], p[1], p[2]))
                .collect();
            let (vertices, triangles) = parry3d_f64::transformation::try_convex_hull(&pts)
                .map_err(|e| DetectError::Shape {
                    body,
                    reason: format!("no convex hull of its points: {e:?}"),
                })?;
            Surface {
                points: vertices.iter().map(|v| [v.x, v.y, v.z]).collect(),
                faces: triangles.iter().map(|t| t.to_vec()).collect(),
            }
        }
        Shape::HalfSpace { normal } => {
            let [t1, t2] = tangent_basis(normal);
            let corner = |a: f64, b: f64| [0, 1, 2].map(|i| extent * (a * t1[i] + b * t2[i]));
            Surface {
                points: vec![
                    corner(-1.0, -1.0),
                    corner(1.0, -1.0),
                    corner(1.0, 1.0),
                    corner(-1.0, 1.0),
                ],
                // (n, t1, t2) is right-handed: t1 then t2 turns counter-clockwise about n.
                faces: vec![vec![0, 1, 2, 3]],
            }
        }
    })
}

/// The half side of a half-space's square in a picture of `scene`: twice (1 m + the largest
/// coordinate of a body's initial position), so the square reaches past every body's start.
pub fn half_space_extent(scene: &RigidScene) -> f64 {
    let reach = scene
        .initial
        .iter()
        .flat_map(|s| s.position)
        .map(f64::abs)
        .fold(0.0, f64::max);
    2.0 * (1.0 + reach)
}

/// The surfaces of every body of `scene`, in order.
pub fn scene_surfaces(scene: &RigidScene) -> Result<Vec<Surface>, DetectError> {
    let extent = half_space_extent(scene);
    scene
        .bodies
        .iter()
        .enumerate()
        .map(|(b, body)| surface(b, &body.shape, extent))
        .collect()
}

/// The profile (radius, z) from the top pole to the bottom one of a sphere of radius r whose
/// upper half is raised by a and lower half lowered by a (a capsule; a = 0: a sphere).
fn round_profile(r: f64, a: f64) -> Vec<(f64, f64)> {
    let half = SEGMENTS / 4;
    let mut profile = Vec::with_capacity(2 * half + 2);
    for i in 0..=half {
        let phi = PI / 2.0 * i as f64 / half as f64;
        profile.push((r * phi.sin(), a + r * phi.cos()));
    }
    // The equator ring again, lowered (a capsule's side), unless the sphere has no side.
    let start = if a > 0.0 { half } else { half + 1 };
    for i in start..2 * half {
        let phi = PI / 2.0 * i as f64 / half as f64;
        profile.push((r * phi.sin(), -a + r * phi.cos()));
    }
    // The bottom pole exactly (sin π is not 0 in floating point).
    profile.push((0.0, -a - r));
    profile
}

/// The surface of revolution about z of a profile (radius, z) running from top to bottom;
/// a profile point of radius 0 is a pole (one vertex), any other a ring of [`SEGMENTS`].
fn revolved(profile: &[(f64, f64)]) -> Surface {
    let mut points = Vec::new();
    // Per profile point: its first vertex and whether it is a pole.
    let mut rings = Vec::with_capacity(profile.len());
    for &(r, z) in profile {
        let first = points.len() as u32;
        if r == 0.0 {
            points.push([0.0, 0.0, z]);
            rings.push((first, true));
        } else {
            for j in 0..SEGMENTS {
                let a = 2.0 * PI * j as f64 / SEGMENTS as f64;
                points.push([r * a.cos(), r * a.sin(), z]);
            }
            rings.push((first, false));
        }
    }
    let n = SEGMENTS as u32;
    let mut faces = Vec::new();
    for w in rings.windows(2) {
        let [(top, top_pole), (bottom, bottom_pole)] = [w[0], w[1]];
        for j in 0..n {
            let k = (j + 1) % n;
            // Going down the profile and counter-clockwise about z, the outward face is
            // (top j, bottom j, bottom k, top k).
            let face = match (top_pole, bottom_pole) {
                (true, true) => continue,
                (true, false) => vec![top, bottom + j, bottom + k],
                (false, true) => vec![top + j, bottom, top + k],
                (false, false) => vec![top + j, bottom + j, bottom + k, top + k],
            };
            faces.push(face);
        }
    }
    Surface { points, faces }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The volume enclosed by a closed mesh of outward faces (divergence theorem, fans of
    /// triangles); positive when every face is counter-clockwise seen from outside.
    fn volume(s: &Surface) -> f64 {
        let mut v = 0.0;
        for f in &s.faces {
            let p0 = s.points[f[0] as usize];
            for w in f[1..].windows(2) {
                let [p1, p2] = [s.points[w[0] as usize], s.points[w[1] as usize]];
                v += p0[0] * (p1[1] * p2[2] - p1[2] * p2[1])
                    - p0[1] * (p1[0] * p2[2] - p1[2] * p2[0])
                    + p0[2] * (p1[0] * p2[1] - p1[1] * p2[0]);
            }
        }
        v / 6.0
    }

    #[test]
    fn closed_surfaces_enclose_their_shapes_volume_with_outward_faces() {
        let box_ = surface(
            0,
            &Shape::Box {
                half_extents: [0.1, 0.2, 0.3],
            },
            1.0,
        )
        .unwrap();
        assert_eq!((box_.points.len(), box_.faces.len()), (8, 6));
        assert!((volume(&box_) - 0.048).abs() < 1e-15);

        // A polygon of 24 sides inscribed in the circle has area ½ n r² sin(2π/n).
        let n = SEGMENTS as f64;
        let disc = 0.5 * n * (2.0 * PI / n).sin();
        let cyl = surface(
            0,
            &Shape::Cylinder {
                radius: 1.0,
                half_height: 0.5,
            },
            1.0,
        )
        .unwrap();
        assert_eq!(cyl.points.len(), 2 + 2 * SEGMENTS);
        assert!((volume(&cyl) - disc).abs() < 1e-12);

        let ball = surface(0, &Shape::Sphere { radius: 1.0 }, 1.0).unwrap();
        // Poles and 11 rings.
        assert_eq!(ball.points.len(), 2 + (SEGMENTS / 2 - 1) * SEGMENTS);
        let v = volume(&ball);
        assert!(v > 0.9 * 4.0 / 3.0 * PI && v < 4.0 / 3.0 * PI, "{v}");
        assert!(
            ball.points.iter().all(|p| {
                ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs() < 1e-15
            })
        );

        // A capsule adds the inscribed prism of its side to its sphere's volume.
        let capsule = surface(
            0,
            &Shape::Capsule {
                radius: 1.0,
                half_height: 0.5,
            },
            1.0,
        )
        .unwrap();
        assert!((volume(&capsule) - v - disc).abs() < 1e-12);

        let hull = surface(
            0,
            &Shape::Convex {
                points: vec![
                    [0.0, 0.0, 0.0],
                    [1.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0],
                    [0.0, 0.0, 1.0],
                    [0.1, 0.1, 0.1],
                ],
            },
            1.0,
        )
        .unwrap();
        assert_eq!(hull.faces.len(), 4);
        assert!((volume(&hull) - 1.0 / 6.0).abs() < 1e-15);
    }

    #[test]
    fn a_half_space_is_a_square_in_its_plane_facing_its_normal() {
        let s = surface(
            0,
            &Shape::HalfSpace {
                normal: [0.0, 0.0, 1.0],
            },
            5.0,
        )
        .unwrap();
        assert_eq!(s.points.len(), 4);
        assert!(s.points.iter().all(|p| p[2] == 0.0));
        assert!(
            s.points
                .iter()
                .all(|p| p[0].abs() == 5.0 && p[1].abs() == 5.0)
        );
        // The face's normal (p1 − p0) × (p2 − p1) points along +z.
        let [p0, p1, p2] = [s.points[0], s.points[1], s.points[2]];
        let (a, b) = (
            [p1[0] - p0[0], p1[1] - p0[1]],
            [p2[0] - p1[0], p2[1] - p1[1]],
        );
        assert!(a[0] * b[1] - a[1] * b[0] > 0.0);
    }
}
