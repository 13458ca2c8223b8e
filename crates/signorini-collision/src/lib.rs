//! Collision detection for Signorini's rigid bodies: parry3d (f64, pinned) behind the core's
//! [`ContactDetector`] trait. The core's shapes become parry shapes once; every call converts the
//! poses (plain arrays) to parry's glam types, finds the candidate pairs with a broad phase, and
//! hands back parry's contact manifolds as the core's [`ContactPoint`]s: witness points, the
//! normal from the first body to the second, the tangents of [`tangent_basis`] and the gap.
//!
//! **Broad phase.** Sweep and prune on the bounding boxes (grown by the margin) along the world
//! axis of largest spread: sort the boxes by their lower bound, and test a pair only when their
//! intervals overlap on that axis and their boxes overlap on all three, so N bodies cost
//! O(N log N) plus the overlapping pairs, not N² narrow-phase tests. Half-spaces have no
//! bounded box: each is paired with every body whose box reaches within the margin of its
//! boundary plane. Narrow phase: parry's `contact_manifolds` (one point per sphere contact,
//! up to four for a box face on a plane, clipped polygons for box/box), called without a
//! persistent workspace so that the points depend on the poses alone (a resumed run detects the
//! same points).

pub mod surface;

use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::math::{Pose as ParryPose, Rotation, Vector};
use parry3d_f64::query::{ContactManifold, DefaultQueryDispatcher, PersistentQueryDispatcher};
use parry3d_f64::shape::SharedShape;
use signorini_core::rigid::{
    Body, ContactDetector, ContactPoint, DetectError, DetectorFactory, Pose, Shape, tangent_basis,
};

/// The detector factory of the service and the CLI.
#[derive(Debug, Clone, Copy, Default)]
pub struct ParryDetectors;

impl DetectorFactory for ParryDetectors {
    fn detector(&self, bodies: &[Body]) -> Result<Box<dyn ContactDetector>, DetectError> {
        Ok(Box::new(ParryDetector::new(bodies)?))
    }
}

/// One body as parry sees it.
struct Collider {
    shape: SharedShape,
    /// The shape's frame in the body frame (a rotation taking parry's y-axis cylinder to the
    /// body z axis), identity otherwise.
    offset: ParryPose,
    fixed: bool,
    half_space: bool,
    kind: &'static str,
}

/// Contact detection with parry3d.
pub struct ParryDetector {
    colliders: Vec<Collider>,
    manifolds: Vec<ContactManifold<(), ()>>,
    /// Scratch of the broad phase: (box, body) of the bounded bodies.
    boxes: Vec<(Aabb, usize)>,
    pairs: Vec<(usize, usize)>,
}

fn vector(a: [f64; 3]) -> Vector {
    Vector::new(a[0], a[1], a[2])
}

fn array(v: Vector) -> [f64; 3] {
    [v.x, v.y, v.z]
}

impl ParryDetector {
    /// Builds the parry shape of every body; a degenerate convex hull is refused naming its
    /// body.
    pub fn new(bodies: &[Body]) -> Result<Self, DetectError> {
        let colliders = bodies
            .iter()
            .enumerate()
            .map(|(i, b)| collider(i, b))
            .collect::<Result<_, _>>()?;
        Ok(Self {
            colliders,
            manifolds: Vec::new(),
            boxes: Vec::new(),
            pairs: Vec::new(),
        })
    }

    /// The candidate pairs (i < j, not both fixed) of the broad phase, sorted.
    fn broad_phase(&mut self, poses: &[ParryPose], margin: f64) {
        self.boxes.clear();
        self.pairs.clear();
        for (i, c) in self.colliders.iter().enumerate() {
            if !c.half_space {
                let aabb = c
                    .shape
                    .compute_aabb(&(poses[i] * c.offset))
                    .loosened(margin);
                self.boxes.push((aabb, i));
            }
        }
        // The axis of largest spread of the box centres.
        let axis = {
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for (b, _) in &self.boxes {
                let c = array(b.center());
                for k in 0..3 {
                    lo[k] = lo[k].min(c[k]);
                    hi[k] = hi[k].max(c[k]);
                }
            }
            (0..3)
                .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
                .unwrap_or(0)
        };
        let low = |b: &Aabb| array(b.mins)[axis];
        let high = |b: &Aabb| array(b.maxs)[axis];
        self.boxes
            .sort_by(|(a, i), (b, j)| low(a).total_cmp(&low(b)).then(i.cmp(j)));
        for (n, (a, i)) in self.boxes.iter().enumerate() {
            for (b, j) in &self.boxes[n + 1..] {
                if low(b) > high(a) {
                    break;
                }
                let both_fixed = self.colliders[*i].fixed && self.colliders[*j].fixed;
                if !both_fixed && a.intersects(b) {
                    self.pairs.push(((*i).min(*j), (*i).max(*j)));
                }
            }
        }
        for (h, c) in self.colliders.iter().enumerate() {
            if !c.half_space {
                continue;
            }
            let normal = poses[h].transform_vector(half_space_normal(&c.shape));
            let origin = poses[h].translation;
            for (b, i) in &self.boxes {
                if self.colliders[*i].fixed {
                    continue;
                }
                // The box corner deepest along −n is within the margin of the plane.
                let deepest = Vector::new(
                    if normal.x > 0.0 { b.mins.x } else { b.maxs.x },
                    if normal.y > 0.0 { b.mins.y } else { b.maxs.y },
                    if normal.z > 0.0 { b.mins.z } else { b.maxs.z },
                );
                if (deepest - origin).dot(normal) <= 0.0 {
                    self.pairs.push((h.min(*i), h.max(*i)));
                }
            }
        }
        self.pairs.sort_unstable();
        self.pairs.dedup();
    }
}

fn half_space_normal(shape: &SharedShape) -> Vector {
    shape
        .as_halfspace()
        .map_or(Vector::new(0.0, 0.0, 1.0), |h| h.normal)
}

fn collider(index: usize, body: &Body) -> Result<Collider, DetectError> {
    let plain = |shape, kind| Collider {
        shape,
        offset: ParryPose::IDENTITY,
        fixed: body.fixed,
        half_space: false,
        kind,
    };
    Ok(match &body.shape {
        Shape::Sphere { radius } => plain(SharedShape::ball(*radius), "sphere"),
        Shape::Box {
            half_extents: [a, b, c],
        } => plain(SharedShape::cuboid(*a, *b, *c), "box"),
        Shape::Capsule {
            radius,
            half_height,
        } => plain(SharedShape::capsule_z(*half_height, *radius), "capsule"),
        Shape::Cylinder {
            radius,
            half_height,
        } => Collider {
            // parry's cylinder is about its y axis; a quarter turn about x takes y to z.
            offset: ParryPose::from_rotation(Rotation::from_rotation_x(
                std::f64::consts::FRAC_PI_2,
            )),
            ..plain(SharedShape::cylinder(*half_height, *radius), "cylinder")
        },
        Shape::Convex { points } => {
            let points: Vec<Vector> = points.iter().map(|p| vector(*p)).collect();
            let hull = SharedShape::convex_hull(&points).ok_or_else(|| DetectError::Shape {
                body: index,
                reason: "the convex hull of the points is degenerate (fewer than 4 points not in one plane)".into(),
            })?;
            plain(hull, "convex")
        }
        Shape::HalfSpace { normal } => Collider {
            half_space: true,
            ..plain(
                SharedShape::halfspace(vector(*normal).normalize()),
                "half_space",
            )
        },
    })
}

fn parry_pose(p: &Pose) -> ParryPose {
    let [w, x, y, z] = p.orientation;
    ParryPose::from_parts(vector(p.position), Rotation::from_xyzw(x, y, z, w))
}

impl ContactDetector for ParryDetector {
    fn detect(
        &mut self,
        poses: &[Pose],
        margin: f64,
        contacts: &mut Vec<ContactPoint>,
    ) -> Result<(), DetectError> {
        contacts.clear();
        let poses: Vec<ParryPose> = poses.iter().map(parry_pose).collect();
        self.broad_phase(&poses, margin);
        let dispatcher = DefaultQueryDispatcher;
        for &(i, j) in &self.pairs {
            let (ci, cj) = (&self.colliders[i], &self.colliders[j]);
            let pos_i = poses[i] * ci.offset;
            let pos_j = poses[j] * cj.offset;
            let pos12 = pos_i.inv_mul(&pos_j);
            self.manifolds.clear();
            dispatcher
                .contact_manifolds(
                    &pos12,
                    ci.shape.as_ref(),
                    cj.shape.as_ref(),
                    margin,
                    &mut self.manifolds,
                    &mut None,
                )
                .map_err(|_| DetectError::Unsupported {
                    first: i,
                    first_shape: ci.kind,
                    second: j,
                    second_shape: cj.kind,
                })?;
            for manifold in &self.manifolds {
                let normal = pos_i.transform_vector(manifold.local_n1).normalize();
                let n = array(normal);
                for point in &manifold.points {
                    if point.dist > margin {
                        continue;
                    }
                    contacts.push(ContactPoint {
                        bodies: [i, j],
                        points: [
                            array(pos_i.transform_point(point.local_p1)),
                            array(pos_j.transform_point(point.local_p2)),
                        ],
                        normal: n,
                        tangents: tangent_basis(n),
                        gap: point.dist,
                        features: [point.fid1.0, point.fid2.0],
                    });
                }
            }
        }
        Ok(())
    }
}
