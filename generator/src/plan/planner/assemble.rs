//! An accepted scene made into a sequence plan: the frames' camera poses
//! and labels, the wrist, the head camera, distractors, the appearance, and
//! the `sampled` record of every value drawn.

use super::search::{Accepted, Candidate};
use super::{ObjectGeometry, Planner, SequenceDraws};
use crate::catalog::GraspPart;
use crate::plan::conditions::PathSample;
use crate::plan::error::Result;
use crate::plan::head_camera::HeadCamera;
use crate::plan::scene::Placement;
use crate::plan::trajectory::frame_tau;
use crate::plan::wrist::{self, WristAngles};
use crate::randomize;
use grasp_schema::plan::{
    substream_seed, FramePlan, ObjectPlacement, Pose, SequenceKey, SequencePlan,
    PLAN_SCHEMA_VERSION,
};
use grasp_schema::Class;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde_json::json;
use std::collections::BTreeMap;

impl Planner {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn build_plan(
        &self,
        key: &SequenceKey,
        geo: &ObjectGeometry,
        part_index: usize,
        part: &GraspPart,
        stream: u64,
        draws: &SequenceDraws,
        accepted: Accepted,
    ) -> Result<SequencePlan> {
        let cfg = &self.config.plan;
        let traj = &cfg.trajectory;
        let duration = cfg.conditions.duration_s(key.condition, traj.duration_s);
        let n = traj.frame_count(duration)?;
        let c = &accepted.candidate;
        let s = c.sample.as_ref().expect("accepted candidates have a path");
        let bx = &geo.boxes[part_index];
        let box_x = c.placement.rotation * (bx.rotation * Vector3::x());
        let wrist = WristAngles::new(
            traj,
            s,
            c.target,
            c.other_end,
            box_x,
            part.pronation,
            stream,
        );
        let class = Class::from(part.grasp_type.preshape());
        let mut frames = frame_poses(traj, n, c, &wrist, class);
        let shake = cfg
            .shake
            .enabled
            .then(|| crate::plan::shake::Shake::sample(&cfg.shake, stream));
        if let Some(shake) = &shake {
            shake.apply(&mut frames);
        }
        let head = self.head_camera(key, geo, &c.placement, stream);
        let elbows = head.as_ref().map(|h| attach_head_camera(h, &mut frames));

        let mut sampled = sampled_record(&accepted, draws, part, &wrist);
        let mut put = |k: &str, v: serde_json::Value| {
            sampled.insert(k.to_string(), v);
        };
        for (k, v) in head.iter().flat_map(|h| h.sampled()) {
            put(k, v);
        }
        if let Some(elbows) = elbows {
            put("head_elbows", json!(elbows));
        }
        if let Some(shake) = &shake {
            put("shake", shake.sampled());
        }
        if let Some(world) = &self.config.dataset.held_out {
            put("held_out", json!(world));
        }

        let (distractors, rejected) = self.distractors(geo, c, s, stream);
        if self.levers.distractors.enabled {
            put("distractor_count", json!(distractors.len()));
            put("distractor_rejected_draws", json!(rejected));
        }
        Ok(SequencePlan {
            schema_version: PLAN_SCHEMA_VERSION,
            dataset_seed: self.config.dataset.seed,
            key: key.clone(),
            stream_seed: stream,
            category: geo.spec.category.clone(),
            grasp_type: part.grasp_type,
            preshape: part.grasp_type.preshape(),
            part_index,
            fps: traj.fps,
            duration_s: n as f64 / traj.fps,
            intrinsics: draws.intrinsics,
            object: object_placement(c, draws),
            target: c.target.into(),
            other_end: c.other_end.into(),
            frames,
            sampled,
            appearance: Some(self.appearance(key, geo, c, stream)),
            distractors,
        })
    }

    /// The sequence's look: object colours, materials, lights, background.
    fn appearance(
        &self,
        key: &SequenceKey,
        geo: &ObjectGeometry,
        c: &Candidate,
        stream: u64,
    ) -> grasp_schema::appearance::Appearance {
        let colors = randomize::color_range(
            &self.levers.object_color,
            geo.spec.color.as_ref(),
            crate::appearance::default_object_hsv(&geo.spec.id),
        );
        let mut look = randomize::sequence_appearance(
            &self.config.appearance,
            &self.levers,
            key.condition,
            stream,
            &colors,
            c.placement.position.into(),
            &self.images,
        );
        // A mesh from a file (a real object) keeps its own surface.
        if geo.spec.mesh.is_procedural() {
            look.object.surface = randomize::object_surface(&self.levers, stream);
        }
        look
    }

    /// The distractors of an accepted scene (none with the lever off).
    fn distractors(
        &self,
        geo: &ObjectGeometry,
        c: &Candidate,
        s: &PathSample,
        stream: u64,
    ) -> (Vec<grasp_schema::plan::Distractor>, u32) {
        let lever = &self.levers.distractors;
        if !lever.enabled {
            return (Vec::new(), 0);
        }
        let n = self.config.plan.validity.curve_segments.max(1);
        let path = s.path.polyline(n);
        let keepout = crate::plan::distractors::Keepout {
            object_center: c.placement.to_world(&geo.sphere_center),
            object_radius: geo.sphere_radius,
            path: &path,
            target: c.target,
        };
        crate::plan::distractors::sample(lever, &self.config.plan.scene, &keepout, stream)
    }

    /// The static head camera of a sequence, from its own sub-stream (None
    /// unless `plan.head_camera.enabled`).
    fn head_camera(
        &self,
        key: &SequenceKey,
        geo: &ObjectGeometry,
        placement: &Placement,
        stream: u64,
    ) -> Option<HeadCamera> {
        let cfg = &self.config.plan;
        if !cfg.head_camera.enabled {
            return None;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(substream_seed(stream, "head_camera"));
        let center = placement.to_world(&geo.sphere_center);
        Some(crate::plan::head_camera::sample(
            &cfg.head_camera,
            &cfg.scene,
            key.condition,
            [placement.position.x, placement.position.y],
            &center,
            &mut rng,
        ))
    }
}

/// Where the accepted scene puts the object, as the plan records it.
fn object_placement(c: &Candidate, draws: &SequenceDraws) -> ObjectPlacement {
    ObjectPlacement {
        pose: Pose {
            position: c.placement.position.into(),
            rotation_wxyz: wrist::to_wxyz(&c.placement.rotation),
        },
        yaw_deg: c.placement.yaw.to_degrees(),
        upside_down: c.placement.upside_down,
        on_table_border: c.placement.on_border,
        scale: 1.0,
        proportions: draws.proportions,
    }
}

/// Puts the head camera's pose on every frame; the elbow of each frame
/// (shoulder to wrist camera), for the plan's record.
fn attach_head_camera(head: &HeadCamera, frames: &mut [FramePlan]) -> Vec<[f64; 3]> {
    let mut elbows = Vec::new();
    for f in frames {
        f.head_camera = Some(head.pose());
        let e = crate::plan::head_camera::elbow(&head.shoulder(), &f.camera.position.into());
        elbows.push([e.x, e.y, e.z]);
    }
    elbows
}

/// The `n` frames' camera poses and labels: the part's class, then
/// `no_grasp` for the tail.
fn frame_poses(
    traj: &crate::plan::TrajectoryConfig,
    n: usize,
    c: &Candidate,
    wrist: &WristAngles,
    class: Class,
) -> Vec<FramePlan> {
    let s = c.sample.as_ref().expect("accepted candidates have a path");
    let tail = traj.tail_frames(n);
    (0..n)
        .map(|i| {
            let tau = frame_tau(i, n);
            let p = s.path.position(tau);
            let q = wrist.camera_rotation(c.target, s, &p, tau);
            FramePlan {
                index: i as u32,
                time_s: i as f64 / traj.fps,
                camera: Pose {
                    position: [p.x, p.y, p.z],
                    rotation_wxyz: wrist::to_wxyz(&q),
                },
                class: if i >= n - tail { Class::NoGrasp } else { class },
                head_camera: None,
            }
        })
        .collect()
}

/// The plan's `sampled` record: every value drawn for the sequence and how
/// the search went (attempts, rejections, tolerance use), for analysis and
/// reproduction.
fn sampled_record(
    accepted: &Accepted,
    draws: &SequenceDraws,
    part: &GraspPart,
    wrist: &WristAngles,
) -> BTreeMap<String, serde_json::Value> {
    let c = &accepted.candidate;
    let s = c.sample.as_ref().expect("accepted candidates have a path");
    let mut sampled = BTreeMap::new();
    let mut put = |k: &str, v: serde_json::Value| {
        sampled.insert(k.to_string(), v);
    };
    put("attempts", json!(accepted.attempts));
    put(
        "rejections",
        json!(accepted
            .rejections
            .iter()
            .map(|(r, n)| (format!("{r:?}"), *n))
            .collect::<BTreeMap<_, _>>()),
    );
    put("object_x", json!(c.placement.position.x));
    put("object_y", json!(c.placement.position.y));
    put("object_yaw_deg", json!(c.placement.yaw.to_degrees()));
    put("upside_down", json!(c.placement.upside_down));
    put(
        "target_end",
        json!(if c.target_sign > 0.0 { "+z" } else { "-z" }),
    );
    for (k, v) in &s.sampled {
        put(k, v.clone());
    }
    put("end", json!(wrist.end.as_slice()));
    put("standoff_m", json!(draws.approach.standoff_m));
    put("aim_offset", json!(draws.approach.aim));
    if let Some((_, forced)) = draws.approach.end {
        put("target_end_forced", json!(accepted.attempts <= forced));
    }
    put("fov_scale", json!(draws.fov_scale));
    if draws.proportions != [1.0; 3] {
        put("proportions", json!(draws.proportions));
    }
    put("principal_point_shift", json!(draws.principal_point_shift));
    put(
        "mesh_tolerance_used",
        json!(accepted.acceptance.mesh_contact_before_box_m.is_some()),
    );
    if let Some(gap) = accepted.acceptance.mesh_contact_before_box_m {
        put("mesh_contact_before_box_m", json!(gap));
    }
    put(
        "pronation_rule",
        json!(format!("{:?}", part.pronation).to_lowercase()),
    );
    put("ps_angle_deg", json!(wrist.ps_angle.to_degrees()));
    put("fe_angle_deg", json!(wrist.fe_angle.to_degrees()));
    wrist.schedule.record(&mut put);
    sampled
}
