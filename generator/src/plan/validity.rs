//! The paper's validity rule: the camera's path towards the target must
//! reach the target part's box before anything else (the object's mesh,
//! another part's box, the table).
//!
//! Boxes and the table are tested in Rust (slab test); the mesh through a
//! [`RayCaster`], which is trimesh in production and a fake in unit tests.
//! Mesh queries are batched: one call per batch of candidate paths.

use crate::geometry::Result;
use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// Validity settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ValidityConfig {
    /// A first contact with the object's mesh at most this far (metres,
    /// along the path) before the target box is accepted. Some annotated
    /// boxes sit a few millimetres under the mesh surface; plans record
    /// when this was used (`sampled.mesh_tolerance_used`).
    pub mesh_tolerance_m: f64,
    /// Reject starts from which the object is not in view (its bounding
    /// sphere's centre outside the image, or the sphere filling the view so
    /// no background shows).
    pub require_object_in_view: bool,
    /// Candidates tested per batched mesh query (the result does not depend
    /// on it: the first valid candidate in draw order always wins).
    pub batch_size: usize,
    /// Chords used to check a curved path.
    pub curve_segments: usize,
}

impl Default for ValidityConfig {
    fn default() -> Self {
        ValidityConfig {
            mesh_tolerance_m: 0.005,
            require_object_in_view: true,
            batch_size: 16,
            curve_segments: 16,
        }
    }
}

/// Batched first-hit ray casts against one mesh, in the mesh's frame.
pub trait RayCaster {
    /// Distance along each unit direction to the first hit, or None.
    fn first_hits(&self, origins: &[[f64; 3]], directions: &[[f64; 3]])
        -> Result<Vec<Option<f64>>>;
}

impl RayCaster for crate::geometry::MeshQuery {
    fn first_hits(
        &self,
        origins: &[[f64; 3]],
        directions: &[[f64; 3]],
    ) -> Result<Vec<Option<f64>>> {
        crate::geometry::MeshQuery::first_hits(self, origins, directions)
    }
}

/// Ray casts against a mesh stretched about its frame's origin by `scale`
/// along X, Y, Z, through the unstretched mesh's caster: a ray's origin
/// and direction shrink by the scale, the direction is made unit again, and
/// the hit distance is divided by the length the unit direction shrank to.
pub struct ScaledCaster {
    inner: std::rc::Rc<dyn RayCaster>,
    scale: Vector3<f64>,
}

impl ScaledCaster {
    pub fn new(inner: std::rc::Rc<dyn RayCaster>, scale: Vector3<f64>) -> ScaledCaster {
        ScaledCaster { inner, scale }
    }
}

impl RayCaster for ScaledCaster {
    fn first_hits(
        &self,
        origins: &[[f64; 3]],
        directions: &[[f64; 3]],
    ) -> Result<Vec<Option<f64>>> {
        let shrink = |v: &[f64; 3]| Vector3::from(*v).component_div(&self.scale);
        let shrunk: Vec<[f64; 3]> = origins.iter().map(|o| shrink(o).into()).collect();
        let lengths: Vec<f64> = directions.iter().map(|d| shrink(d).norm()).collect();
        let units: Vec<[f64; 3]> = directions
            .iter()
            .zip(&lengths)
            .map(|(d, l)| (shrink(d) / *l).into())
            .collect();
        let hits = self.inner.first_hits(&shrunk, &units)?;
        Ok(hits
            .into_iter()
            .zip(lengths)
            .map(|(h, l)| h.map(|t| t / l))
            .collect())
    }
}

/// An oriented box: centre, rotation (frame-from-box) and half extents.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obb {
    pub center: Vector3<f64>,
    pub rotation: UnitQuaternion<f64>,
    pub half: Vector3<f64>,
}

impl Obb {
    /// Entry parameter t in [0, 1] of the segment a -> b into the box (0 if
    /// a is inside), or None when the segment misses it.
    pub fn segment_entry(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> Option<f64> {
        let la = self.rotation.inverse_transform_vector(&(a - self.center));
        let lb = self.rotation.inverse_transform_vector(&(b - self.center));
        slab_entry(&la, &(lb - la), &self.half)
    }

    /// The box stretched about the frame's origin by `scale` along X, Y, Z.
    /// A box whose axes are the frame's (every built-in part but two) stays
    /// exact; a tilted one becomes the box along its stretched axes, made
    /// orthogonal again (a parallelogram's nearest box, close for the
    /// lever's few per cent).
    pub fn stretched(&self, scale: &Vector3<f64>) -> Obb {
        let axes = self.rotation.to_rotation_matrix().into_inner();
        let mut stretched = axes;
        let mut half = self.half;
        for i in 0..3 {
            let column = axes.column(i).component_mul(scale);
            half[i] *= column.norm();
            stretched.set_column(i, &column);
        }
        let rotation = UnitQuaternion::from_matrix_eps(&stretched, 1e-12, 100, self.rotation);
        Obb {
            center: self.center.component_mul(scale),
            rotation,
            half,
        }
    }

    /// Euclidean distance from a point to the box (0 inside).
    pub fn distance(&self, p: &Vector3<f64>) -> f64 {
        let l = self.rotation.inverse_transform_vector(&(p - self.center));
        let d = l.abs() - self.half;
        d.map(|x| x.max(0.0)).norm()
    }
}

/// Slab test of the segment o + t d, t in [0, 1], against the axis-aligned
/// box [-half, half].
fn slab_entry(o: &Vector3<f64>, d: &Vector3<f64>, half: &Vector3<f64>) -> Option<f64> {
    // Touching the box surface at the very end counts as reaching it.
    const EPS: f64 = 1e-9;
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    for k in 0..3 {
        let h = half[k] + EPS * half[k].max(1.0);
        if d[k].abs() < 1e-300 {
            if o[k].abs() > h {
                return None;
            }
            continue;
        }
        let (mut a, mut b) = ((-h - o[k]) / d[k], (h - o[k]) / d[k]);
        if a > b {
            std::mem::swap(&mut a, &mut b);
        }
        t0 = t0.max(a);
        t1 = t1.min(b);
        if t0 > t1 {
            return None;
        }
    }
    Some(t0)
}

/// Axis-aligned box (the table slab) as an Obb.
pub fn aabb(min: [f64; 3], max: [f64; 3]) -> Obb {
    let (min, max) = (Vector3::from(min), Vector3::from(max));
    Obb {
        center: (min + max) / 2.0,
        rotation: UnitQuaternion::identity(),
        half: (max - min) / 2.0,
    }
}

/// Why a candidate path was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Rejection {
    /// The object's mesh is reached before the target box.
    MeshFirst,
    /// Another part's box is reached first.
    OtherBoxFirst,
    /// The table is reached first.
    TableFirst,
    /// The start is outside the accepted distance range.
    StartDistance,
    /// The object is out of view (or fills it) at the start.
    NotInView,
    /// The path never reaches the target box.
    MissesTarget,
}

impl Rejection {
    pub fn describe(self) -> &'static str {
        match self {
            Rejection::MeshFirst => "the path hits the object's mesh before the target box",
            Rejection::OtherBoxFirst => "the path enters another part's box first",
            Rejection::TableFirst => "the path hits the table first",
            Rejection::StartDistance => "the start is outside the distance range",
            Rejection::NotInView => "the object is not in view at the start",
            Rejection::MissesTarget => "the path never reaches the target box",
        }
    }
}

/// What the check found for an accepted path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Acceptance {
    /// Distance (metres, along the path) by which a mesh contact preceded
    /// the target box; Some only when the tolerance was needed.
    pub mesh_contact_before_box_m: Option<f64>,
}

/// The scene obstacles of one candidate, in the object frame (boxes, mesh)
/// and the world frame (table).
pub struct Obstacles<'a> {
    pub target: Obb,
    pub others: &'a [Obb],
    /// The table slab, already expressed in the object frame.
    pub table: Obb,
}

/// A path as a polyline in the object frame; its last point is the target.
pub struct PolylineCheck<'a> {
    pub points: Vec<Vector3<f64>>,
    pub obstacles: Obstacles<'a>,
}

/// Rust-side first contacts of one chord.
struct ChordHits {
    target: Option<f64>,
    other: Option<f64>,
    table: Option<f64>,
}

impl PolylineCheck<'_> {
    fn chord_hits(&self, k: usize) -> ChordHits {
        let (a, b) = (&self.points[k], &self.points[k + 1]);
        let o = &self.obstacles;
        ChordHits {
            target: o.target.segment_entry(a, b),
            other: o
                .others
                .iter()
                .filter_map(|bx| bx.segment_entry(a, b))
                .min_by(f64::total_cmp),
            table: o.table.segment_entry(a, b),
        }
    }

    /// Number of leading chords that need a mesh query: up to and including
    /// the first chord with a box or table contact.
    fn chords_to_query(&self) -> usize {
        let n = self.points.len().saturating_sub(1);
        for k in 0..n {
            let h = self.chord_hits(k);
            if h.target.is_some() || h.other.is_some() || h.table.is_some() {
                return k + 1;
            }
        }
        n
    }
}

/// Checks a batch of polylines with one mesh query. Returns, per candidate,
/// acceptance or the reason for rejection.
pub fn check_batch(
    checks: &[PolylineCheck<'_>],
    mesh: &dyn RayCaster,
    tolerance_m: f64,
) -> Result<Vec<Result<Acceptance, Rejection>>> {
    let mut origins = Vec::new();
    let mut dirs = Vec::new();
    let mut spans = Vec::with_capacity(checks.len());
    for c in checks {
        let n = c.chords_to_query();
        let first = origins.len();
        for k in 0..n {
            let (a, b) = (c.points[k], c.points[k + 1]);
            let d = b - a;
            let len = d.norm();
            let dir = if len > 0.0 { d / len } else { Vector3::z() };
            origins.push([a.x, a.y, a.z]);
            dirs.push([dir.x, dir.y, dir.z]);
        }
        spans.push((first, n));
    }
    let hits = if origins.is_empty() {
        Vec::new()
    } else {
        mesh.first_hits(&origins, &dirs)?
    };
    Ok(checks
        .iter()
        .zip(spans)
        .map(|(c, (first, n))| decide(c, &hits[first..first + n], tolerance_m))
        .collect())
}

fn decide(
    c: &PolylineCheck<'_>,
    mesh_hits: &[Option<f64>],
    tolerance_m: f64,
) -> Result<Acceptance, Rejection> {
    for (k, mesh_hit) in mesh_hits.iter().enumerate() {
        let len = (c.points[k + 1] - c.points[k]).norm();
        if len == 0.0 {
            continue;
        }
        let h = c.chord_hits(k);
        // Mesh distances are along the chord; beyond its end they don't count.
        let mesh = mesh_hit
            .filter(|d| *d <= len * (1.0 + 1e-9))
            .map(|d| d / len);
        let blockers = [h.other, h.table, mesh];
        if h.target.is_none() && blockers.iter().all(Option::is_none) {
            continue;
        }
        let Some(t_box) = h.target else {
            return Err(first_blocker(h.other, h.table, mesh));
        };
        if h.other.is_some_and(|t| t < t_box) {
            return Err(Rejection::OtherBoxFirst);
        }
        if h.table.is_some_and(|t| t < t_box) {
            return Err(Rejection::TableFirst);
        }
        return match mesh {
            Some(t) if t < t_box => {
                let gap = (t_box - t) * len;
                if gap <= tolerance_m {
                    Ok(Acceptance {
                        mesh_contact_before_box_m: Some(gap),
                    })
                } else {
                    Err(Rejection::MeshFirst)
                }
            }
            _ => Ok(Acceptance {
                mesh_contact_before_box_m: None,
            }),
        };
    }
    Err(Rejection::MissesTarget)
}

fn first_blocker(other: Option<f64>, table: Option<f64>, mesh: Option<f64>) -> Rejection {
    [
        (other, Rejection::OtherBoxFirst),
        (table, Rejection::TableFirst),
        (mesh, Rejection::MeshFirst),
    ]
    .into_iter()
    .filter_map(|(t, r)| t.map(|t| (t, r)))
    .min_by(|a, b| a.0.total_cmp(&b.0))
    .map(|(_, r)| r)
    .unwrap_or(Rejection::MissesTarget)
}

/// A fake mesh for tests: the surface of an axis-aligned box.
pub struct BoxMesh(pub Obb);

impl RayCaster for BoxMesh {
    fn first_hits(
        &self,
        origins: &[[f64; 3]],
        directions: &[[f64; 3]],
    ) -> Result<Vec<Option<f64>>> {
        const FAR: f64 = 1e6;
        Ok(origins
            .iter()
            .zip(directions)
            .map(|(o, d)| {
                let o = Vector3::from(*o);
                let d = Vector3::from(*d);
                // A ray starting inside the solid hits the surface on exit;
                // match trimesh by reporting the exit for inside origins.
                if self.0.distance(&o) == 0.0 {
                    let far = o + d * FAR;
                    return self.0.segment_entry(&far, &o).map(|t| (1.0 - t) * FAR);
                }
                self.0.segment_entry(&o, &(o + d * FAR)).map(|t| t * FAR)
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(c: [f64; 3], h: f64) -> Obb {
        Obb {
            center: Vector3::from(c),
            rotation: UnitQuaternion::identity(),
            half: Vector3::repeat(h),
        }
    }

    /// A unit cube on the origin's XY plane stretched by (2, 1, 0.5) is the
    /// box of half extents (1, 0.5, 0.25) centred at z = 0.25: the stretched
    /// caster must hit it where that box's own caster does, along tilted
    /// rays too (whose distances change by the stretch unevenly).
    #[test]
    fn a_scaled_caster_hits_the_stretched_mesh() {
        let unit = std::rc::Rc::new(BoxMesh(cube([0.0, 0.0, 0.5], 0.5)));
        let scale = Vector3::new(2.0, 1.0, 0.5);
        let stretched = ScaledCaster::new(unit.clone(), scale);
        let want_box = cube([0.0, 0.0, 0.5], 0.5).stretched(&scale);
        assert!((want_box.half - Vector3::new(1.0, 0.5, 0.25)).norm() < 1e-12);
        assert!((want_box.center - Vector3::new(0.0, 0.0, 0.25)).norm() < 1e-12);
        let big = BoxMesh(want_box);
        let tilted = Vector3::new(1.0, 0.3, -0.2).normalize();
        let origins = [
            [-5.0, 0.0, 0.2],
            [0.0, 0.0, 1.0],
            [3.0, 3.0, 3.0],
            [0.5, 0.2, 9.0],
            [-4.0, -1.0, 0.9],
        ];
        let directions = [
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, -1.0],
            tilted.into(),
        ];
        let want = big.first_hits(&origins, &directions).unwrap();
        let got = stretched.first_hits(&origins, &directions).unwrap();
        assert_eq!(want.iter().filter(|h| h.is_some()).count(), 3);
        for (g, w) in got.iter().zip(&want) {
            match (g, w) {
                // BoxMesh casts 1e6 m segments: distances are good to about 1e-9.
                (Some(g), Some(w)) => assert!((g - w).abs() < 1e-6, "{g} against {w}"),
                (None, None) => {}
                _ => panic!("{got:?} against {want:?}"),
            }
        }
        // A uniform stretch is a plain resize: distances scale with it.
        let doubled = ScaledCaster::new(unit, Vector3::repeat(2.0));
        let hit = doubled
            .first_hits(&[[-5.0, 0.0, 1.0]], &[[1.0, 0.0, 0.0]])
            .unwrap();
        assert!((hit[0].unwrap() - 4.0).abs() < 1e-6, "{hit:?}");
    }

    /// A tilted box stretched along the frame's axes keeps its centre
    /// mapped exactly and stays a rotation with positive extents; an
    /// axis-aligned one is stretched exactly.
    #[test]
    fn a_stretched_box() {
        let tilted = Obb {
            center: Vector3::new(0.1, -0.2, 0.3),
            rotation: UnitQuaternion::from_euler_angles(0.3, -0.2, 0.7),
            half: Vector3::new(0.01, 0.02, 0.03),
        };
        let scale = Vector3::new(1.1, 0.95, 0.96);
        let s = tilted.stretched(&scale);
        assert!((s.center - Vector3::new(0.11, -0.19, 0.288)).norm() < 1e-12);
        assert!(s.half.iter().all(|&h| h > 0.0));
        // Each stretched axis is within the stretch of the original one.
        for i in 0..3 {
            let ratio = s.half[i] / tilted.half[i];
            assert!((0.95..=1.1).contains(&ratio), "axis {i}: {ratio}");
        }
        let aligned = cube([0.0, 0.0, 0.0], 1.0).stretched(&scale);
        assert!((aligned.half - scale).norm() < 1e-12);
        assert!(aligned.rotation.angle() < 1e-9);
    }

    #[test]
    fn slab_entry_parameters() {
        let b = cube([0.0, 0.0, 0.0], 1.0);
        let a = Vector3::new(-3.0, 0.0, 0.0);
        assert!(
            (b.segment_entry(&a, &Vector3::new(3.0, 0.0, 0.0)).unwrap() - 1.0 / 3.0).abs() < 1e-8
        );
        assert_eq!(b.segment_entry(&a, &Vector3::new(-2.0, 0.0, 0.0)), None);
        // Ending exactly on the face counts.
        assert!(b.segment_entry(&a, &Vector3::new(-1.0, 0.0, 0.0)).is_some());
        assert_eq!(b.segment_entry(&Vector3::zeros(), &a), Some(0.0));
        // A rotated box.
        let r = Obb {
            rotation: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.7),
            ..cube([1.0, 2.0, 0.0], 0.5)
        };
        assert!(r
            .segment_entry(&Vector3::new(1.0, 2.0, 5.0), &Vector3::new(1.0, 2.0, -5.0))
            .is_some());
        assert!(r.distance(&Vector3::new(1.0, 2.0, 0.0)) == 0.0);
    }

    fn check<'a>(points: Vec<Vector3<f64>>, target: Obb, others: &'a [Obb]) -> PolylineCheck<'a> {
        PolylineCheck {
            points,
            obstacles: Obstacles {
                target,
                others,
                table: aabb([-1.0, -1.0, -0.05], [1.0, 1.0, 0.0]),
            },
        }
    }

    #[test]
    fn target_box_in_front_of_the_mesh_is_valid_and_behind_is_not() {
        // Object: a 10 cm cube on the table; the target box covers its top.
        let mesh = BoxMesh(cube([0.0, 0.0, 0.05], 0.05));
        let top = Obb {
            half: Vector3::new(0.02, 0.02, 0.01),
            ..cube([0.0, 0.0, 0.1], 0.0)
        };
        let target = Vector3::new(0.0, 0.0, 0.11);
        let from_above = check(vec![Vector3::new(0.0, 0.0, 0.6), target], top, &[]);
        // Coming from the side, low: the cube's wall is in the way.
        let side_target = Vector3::new(0.0, 0.0, 0.09);
        let from_side = check(vec![Vector3::new(-0.6, 0.0, 0.08), side_target], top, &[]);
        let r = check_batch(&[from_above, from_side], &mesh, 0.0).unwrap();
        assert_eq!(
            r[0],
            Ok(Acceptance {
                mesh_contact_before_box_m: None
            })
        );
        assert_eq!(r[1], Err(Rejection::MeshFirst));
    }

    #[test]
    fn tolerance_accepts_a_box_just_under_the_surface() {
        let mesh = BoxMesh(cube([0.0, 0.0, 0.05], 0.05));
        // Box 3 mm under the top face.
        let sunk = Obb {
            half: Vector3::new(0.02, 0.02, 0.005),
            ..cube([0.0, 0.0, 0.092], 0.0)
        };
        let pts = || vec![Vector3::new(0.0, 0.0, 0.6), Vector3::new(0.0, 0.0, 0.097)];
        let strict = check_batch(&[check(pts(), sunk, &[])], &BoxMesh(mesh.0), 0.0).unwrap();
        assert_eq!(strict[0], Err(Rejection::MeshFirst));
        let lenient = check_batch(&[check(pts(), sunk, &[])], &BoxMesh(mesh.0), 0.005).unwrap();
        let gap = lenient[0].unwrap().mesh_contact_before_box_m.unwrap();
        assert!((gap - 0.003).abs() < 1e-9, "{gap}");
    }

    #[test]
    fn other_box_and_table_block() {
        let far_mesh = BoxMesh(cube([50.0, 0.0, 0.0], 0.1));
        let target = cube([0.5, 0.0, 0.1], 0.02);
        let other = [cube([0.25, 0.0, 0.1], 0.02)];
        let through_other = check(
            vec![Vector3::new(0.0, 0.0, 0.1), Vector3::new(0.48, 0.0, 0.1)],
            target,
            &other,
        );
        let through_table = check(
            vec![Vector3::new(0.5, 0.0, -0.5), Vector3::new(0.5, 0.0, 0.08)],
            target,
            &[],
        );
        let r = check_batch(&[through_other, through_table], &far_mesh, 0.005).unwrap();
        assert_eq!(
            r,
            vec![Err(Rejection::OtherBoxFirst), Err(Rejection::TableFirst)]
        );
    }

    #[test]
    fn curved_polyline_blocked_on_an_early_chord() {
        let mesh = BoxMesh(cube([0.3, 0.0, 0.1], 0.1));
        let target = cube([0.8, 0.0, 0.1], 0.02);
        // The first chord crosses the mesh; the last reaches the target.
        let pts = vec![
            Vector3::new(0.0, 0.0, 0.1),
            Vector3::new(0.6, 0.0, 0.1),
            Vector3::new(0.78, 0.0, 0.1),
        ];
        let r = check_batch(&[check(pts, target, &[])], &mesh, 0.005).unwrap();
        assert_eq!(r[0], Err(Rejection::MeshFirst));
    }
}
