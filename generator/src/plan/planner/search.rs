//! The validity search: candidate scenes drawn from the sequence's
//! `scene` sub-stream, cheap checks first, then batched ray casts along
//! the approach path until one is accepted.

use super::{ObjectGeometry, Planner, SequenceDraws};
use crate::plan::conditions::{sample_path, PathContext, PathSample};
use crate::plan::error::{PlanError, Result};
use crate::plan::scene::{sample_placement, Placement};
use crate::plan::validity::{
    aabb, check_batch, Acceptance, Obb, Obstacles, PolylineCheck, Rejection,
};
use crate::randomize::ApproachDraw;
use grasp_schema::plan::{substream_seed, CameraIntrinsics};
use grasp_schema::Condition;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

/// A drawn candidate scene.
pub(super) struct Candidate {
    pub(super) placement: Placement,
    pub(super) target_sign: f64,
    pub(super) target: Vector3<f64>,
    pub(super) other_end: Vector3<f64>,
    pub(super) sample: Option<PathSample>,
}

pub(super) struct Accepted {
    pub(super) candidate: Candidate,
    pub(super) acceptance: Acceptance,
    pub(super) attempts: u32,
    pub(super) rejections: BTreeMap<Rejection, u32>,
}

impl Planner {
    fn path_context(&self, condition: Condition, standoff: f64) -> PathContext<'_> {
        let p = &self.config.plan;
        PathContext {
            condition,
            presets: &p.conditions,
            region: &p.camera.start,
            scene: &p.scene,
            standoff,
            curve_segments: p.validity.curve_segments,
        }
    }

    /// Candidate number `attempt` (0-based) of the search.
    fn draw(
        &self,
        geo: &ObjectGeometry,
        part_index: usize,
        ctx: &PathContext<'_>,
        approach: &ApproachDraw,
        attempt: u32,
        rng: &mut ChaCha8Rng,
    ) -> Candidate {
        let part = &geo.spec.parts[part_index];
        let placement = sample_placement(&self.config.plan.scene, part, geo.z_range, rng);
        // Always drawn, so the stream is the same whether or not the
        // approach_ends lever forces the end.
        let random_sign = if rng.gen::<bool>() { 1.0 } else { -1.0 };
        let target_sign = match approach.end {
            Some((sign, forced)) if attempt < forced => sign,
            _ => random_sign,
        };
        let bx = &geo.boxes[part_index];
        let [u, v] = approach.aim;
        let end = |sign: f64| {
            bx.center + bx.rotation * Vector3::new(u * bx.half.x, v * bx.half.y, sign * bx.half.z)
        };
        let target = placement.to_world(&end(target_sign));
        let other_end = placement.to_world(&end(-target_sign));
        let sample = sample_path(ctx, &target, rng);
        Candidate {
            placement,
            target_sign,
            target,
            other_end,
            sample,
        }
    }

    /// Cheap Rust-side checks before any ray cast.
    fn precheck(
        &self,
        geo: &ObjectGeometry,
        c: &Candidate,
        condition: Condition,
        k: &CameraIntrinsics,
    ) -> Result<(), Rejection> {
        let cfg = &self.config.plan;
        let s = c.sample.as_ref().ok_or(Rejection::StartDistance)?;
        let scale = if condition == Condition::Seated {
            cfg.conditions.seated.distance_scale
        } else {
            1.0
        };
        let [lo, hi] = cfg.camera.start.distance_m;
        if s.view_distance < lo * scale || s.view_distance > hi * scale {
            return Err(Rejection::StartDistance);
        }
        if cfg.validity.require_object_in_view && !object_in_view(geo, c, s, k) {
            return Err(Rejection::NotInView);
        }
        Ok(())
    }

    fn polyline(&self, c: &Candidate) -> Vec<Vector3<f64>> {
        let s = c.sample.as_ref().expect("prechecked");
        let n = self.config.plan.validity.curve_segments.max(1);
        let mut pts = s.path.polyline(n);
        if matches!(s.path, crate::plan::trajectory::Path::Straight { .. }) {
            pts.pop(); // the straight segment runs start -> target directly
        }
        pts.push(c.target);
        pts.iter().map(|p| c.placement.to_object(p)).collect()
    }

    pub(super) fn search(
        &self,
        geo: &ObjectGeometry,
        part_index: usize,
        condition: Condition,
        stream: u64,
        draws: &SequenceDraws,
    ) -> Result<Accepted> {
        let cfg = &self.config.plan;
        let ctx = self.path_context(condition, draws.approach.standoff_m);
        let mut rng = ChaCha8Rng::seed_from_u64(substream_seed(stream, "scene"));
        let (slab_min, slab_max) = cfg.scene.table_slab();
        let table_world = aabb(slab_min, slab_max);
        let others: Vec<Obb> = geo
            .boxes
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != part_index)
            .map(|(_, b)| *b)
            .collect();
        let max = cfg.trajectory.max_attempts;
        let mut rejections = BTreeMap::new();
        let (mut drawn, mut batch) = (0u32, 1u32);
        while drawn < max {
            let count = batch.min(max - drawn);
            let candidates: Vec<Candidate> = (0..count)
                .map(|i| self.draw(geo, part_index, &ctx, &draws.approach, drawn + i, &mut rng))
                .collect();
            let pre: Vec<Result<(), Rejection>> = candidates
                .iter()
                .map(|c| self.precheck(geo, c, condition, &draws.intrinsics))
                .collect();
            let checks: Vec<PolylineCheck<'_>> = candidates
                .iter()
                .zip(&pre)
                .filter(|(_, p)| p.is_ok())
                .map(|(c, _)| PolylineCheck {
                    points: self.polyline(c),
                    obstacles: Obstacles {
                        target: geo.boxes[part_index],
                        others: &others,
                        table: Obb {
                            center: c.placement.to_object(&table_world.center),
                            rotation: c.placement.rotation.inverse(),
                            half: table_world.half,
                        },
                    },
                })
                .collect();
            let mut results =
                check_batch(&checks, geo.caster.as_ref(), cfg.validity.mesh_tolerance_m)?
                    .into_iter();
            for (i, (c, p)) in candidates.into_iter().zip(pre).enumerate() {
                let outcome = match p {
                    Ok(()) => results.next().expect("one result per check"),
                    Err(r) => Err(r),
                };
                match outcome {
                    Ok(acceptance) => {
                        return Ok(Accepted {
                            candidate: c,
                            acceptance,
                            attempts: drawn + i as u32 + 1,
                            rejections,
                        })
                    }
                    Err(r) => *rejections.entry(r).or_insert(0) += 1,
                }
            }
            drawn += count;
            batch = (batch * 2).min(cfg.validity.batch_size.max(1) as u32);
        }
        let reasons: Vec<String> = rejections
            .iter()
            .map(|(r, n)| format!("{n} x {}", r.describe()))
            .collect();
        Err(PlanError::NoApproach {
            object: geo.spec.id.clone(),
            part: geo.spec.parts[part_index].name.clone(),
            condition,
            attempts: max,
            reasons: reasons.join("; "),
        })
    }
}

/// The object's bounding-sphere centre lies inside the image and the sphere
/// does not fill it, seen from the view point looking at the target with
/// the sequence's lens `k`.
fn object_in_view(
    geo: &ObjectGeometry,
    c: &Candidate,
    s: &PathSample,
    k: &CameraIntrinsics,
) -> bool {
    let half = k.fov_x_deg.min(k.fov_y_deg).to_radians() / 2.0;
    let center = c.placement.to_world(&geo.sphere_center);
    let to_center = center - s.view_point;
    let dist = to_center.norm();
    if dist <= geo.sphere_radius {
        return false;
    }
    let view = c.target - s.view_point;
    let off_axis = view.angle(&to_center);
    let angular_radius = (geo.sphere_radius / dist).asin();
    off_axis < 0.9 * half && angular_radius < half
}
