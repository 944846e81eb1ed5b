//! The planner: scene sampling, the validity search and frame generation.

use super::conditions::{sample_path, PathContext, PathSample};
use super::scene::{sample_placement, Placement};
use super::selection::selected_pairs;
use super::trajectory::frame_tau;
use super::validity::{
    aabb, check_batch, Acceptance, Obb, Obstacles, PolylineCheck, RayCaster, Rejection,
    ScaledCaster,
};
use super::wrist::{self, WristAngles};
use crate::catalog::{Catalog, GraspPart, ObjectSpec, TriMesh};
use crate::config::GeneratorConfig;
use crate::randomize::{self, ApproachDraw};
use anyhow::{bail, Context, Result};
use grasp_schema::plan::{
    substream_seed, CameraIntrinsics, FramePlan, ObjectPlacement, Pose, SequenceKey, SequencePlan,
    PLAN_SCHEMA_VERSION,
};
use grasp_schema::{Class, Condition};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::json;
use std::collections::BTreeMap;
use std::rc::Rc;

/// One object's geometry as the planner needs it.
pub struct ObjectGeometry {
    pub spec: ObjectSpec,
    /// Ray casts against the object's mesh (object frame).
    pub caster: Rc<dyn RayCaster>,
    /// Extent of the mesh along the object's Z (min, max).
    pub z_range: [f64; 2],
    /// Bounding sphere of the mesh (object frame).
    pub sphere_center: Vector3<f64>,
    pub sphere_radius: f64,
    /// The parts' boxes, in the catalog's part order (object frame).
    pub boxes: Vec<Obb>,
    /// Up to 6000 mesh triangles, for drawing the object's silhouette.
    pub outline: Vec<[Vector3<f64>; 3]>,
}

impl ObjectGeometry {
    pub fn new(spec: ObjectSpec, mesh: &TriMesh, caster: Box<dyn RayCaster>) -> Result<Self> {
        anyhow::ensure!(
            !mesh.vertices.is_empty(),
            "object {}: the mesh has no vertices",
            spec.id
        );
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for v in &mesh.vertices {
            let v = Vector3::from(*v);
            lo = lo.inf(&v);
            hi = hi.sup(&v);
        }
        let center = (lo + hi) / 2.0;
        let radius = mesh
            .vertices
            .iter()
            .map(|v| (Vector3::from(*v) - center).norm())
            .fold(0.0, f64::max);
        let boxes = spec
            .parts
            .iter()
            .map(|p| part_box(&spec.id, p))
            .collect::<Result<Vec<_>>>()?;
        Ok(ObjectGeometry {
            spec,
            caster: Rc::from(caster),
            z_range: [lo.z, hi.z],
            sphere_center: center,
            sphere_radius: radius,
            boxes,
            outline: mesh
                .faces
                .iter()
                .step_by(mesh.faces.len().div_ceil(6000).max(1))
                .filter(|f| f.iter().all(|&i| (i as usize) < mesh.vertices.len()))
                .map(|f| f.map(|i| Vector3::from(mesh.vertices[i as usize])))
                .collect(),
        })
    }
}

impl ObjectGeometry {
    /// The same object scaled uniformly about its frame's origin: mesh,
    /// part boxes and every derived extent. Ray casts go through the
    /// catalog-size mesh, so scaling builds no new mesh query.
    pub fn scaled(&self, scale: f64) -> ObjectGeometry {
        let mut spec = self.spec.clone();
        for p in &mut spec.parts {
            p.center = p.center.map(|c| c * scale);
            p.size = p.size.map(|c| c * scale);
        }
        ObjectGeometry {
            spec,
            caster: Rc::new(ScaledCaster::new(self.caster.clone(), scale)),
            z_range: self.z_range.map(|z| z * scale),
            sphere_center: self.sphere_center * scale,
            sphere_radius: self.sphere_radius * scale,
            boxes: self
                .boxes
                .iter()
                .map(|b| Obb {
                    center: b.center * scale,
                    rotation: b.rotation,
                    half: b.half * scale,
                })
                .collect(),
            outline: self.outline.iter().map(|t| t.map(|v| v * scale)).collect(),
        }
    }
}

fn part_box(object: &str, p: &GraspPart) -> Result<Obb> {
    let q = p.rotation_wxyz;
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    anyhow::ensure!(
        norm.is_finite() && norm > 1e-9,
        "object {object}, part {}: rotation_wxyz {q:?} is not a rotation",
        p.name
    );
    anyhow::ensure!(
        p.size.iter().all(|s| s.is_finite() && *s > 0.0),
        "object {object}, part {}: size {:?} must be positive",
        p.name,
        p.size
    );
    Ok(Obb {
        center: Vector3::from(p.center),
        rotation: wrist::from_wxyz(q),
        half: Vector3::from(p.size) / 2.0,
    })
}

/// Plans sequences. Holds each object's mesh query.
pub struct Planner {
    config: GeneratorConfig,
    objects: BTreeMap<String, ObjectGeometry>,
    /// `[appearance] image_dir`'s textures, listed once.
    images: Vec<String>,
    /// `[randomize]` as it acts (every lever off with its master switch off).
    levers: crate::randomize::RandomizeConfig,
}

/// Every sequence the config asks for, in a deterministic order (pair,
/// condition, index).
pub fn sequence_keys(config: &GeneratorConfig, catalog: &Catalog) -> Vec<SequenceKey> {
    let d = &config.dataset;
    let mut keys = Vec::new();
    for (object, part) in selected_pairs(&config.dataset, catalog) {
        for &condition in &d.conditions {
            for index in 0..d.sequences_per_pair {
                keys.push(SequenceKey {
                    object: object.id.clone(),
                    part: part.name.clone(),
                    index,
                    condition,
                });
            }
        }
    }
    keys
}

/// A drawn candidate scene.
struct Candidate {
    placement: Placement,
    target_sign: f64,
    target: Vector3<f64>,
    other_end: Vector3<f64>,
    sample: Option<PathSample>,
}

/// The values of a sequence drawn before its search: the lens and the
/// approach levers.
struct SequenceDraws {
    intrinsics: CameraIntrinsics,
    fov_scale: f64,
    principal_point_shift: [f64; 2],
    approach: ApproachDraw,
    /// `[randomize.object_scale]`'s factor (1 with the lever off).
    object_scale: f64,
}

struct Accepted {
    candidate: Candidate,
    acceptance: Acceptance,
    attempts: u32,
    rejections: BTreeMap<Rejection, u32>,
}

impl Planner {
    /// Builds mesh queries (trimesh) for every object the config selects.
    pub fn new(config: &GeneratorConfig, catalog: &Catalog) -> Result<Planner> {
        config.plan.validate()?;
        let mut geometries = Vec::new();
        let mut seen = std::collections::BTreeSet::new();
        for (object, _) in selected_pairs(&config.dataset, catalog) {
            if !seen.insert(object.id.clone()) {
                continue;
            }
            let mesh = object
                .mesh()
                .with_context(|| format!("loading the mesh of object {}", object.id))?;
            let query = crate::geometry::MeshQuery::new(&mesh)
                .with_context(|| format!("building the mesh query of object {}", object.id))?;
            geometries.push(ObjectGeometry::new(object.clone(), &mesh, Box::new(query))?);
        }
        Planner::from_geometries(config, geometries)
    }

    /// A planner over prepared geometries (any [`RayCaster`]).
    pub fn from_geometries(
        config: &GeneratorConfig,
        objects: Vec<ObjectGeometry>,
    ) -> Result<Planner> {
        config.validate()?;
        Ok(Planner {
            config: config.clone(),
            objects: objects
                .into_iter()
                .map(|g| (g.spec.id.clone(), g))
                .collect(),
            images: config.appearance.images()?,
            levers: config.randomize.effective(),
        })
    }

    pub fn config(&self) -> &GeneratorConfig {
        &self.config
    }

    pub fn object(&self, id: &str) -> Option<&ObjectGeometry> {
        self.objects.get(id)
    }

    /// Plans one sequence: a pure function of the key, the dataset seed and
    /// the config.
    pub fn plan(&self, key: &SequenceKey) -> Result<SequencePlan> {
        let geo = self.objects.get(&key.object).with_context(|| {
            format!(
                "unknown object '{}' (planner has: {})",
                key.object,
                self.objects.keys().cloned().collect::<Vec<_>>().join(", ")
            )
        })?;
        let (part_index, part) = geo
            .spec
            .parts
            .iter()
            .enumerate()
            .find(|(_, p)| p.name == key.part)
            .with_context(|| {
                format!(
                    "object {} has no part '{}' (parts: {})",
                    key.object,
                    key.part,
                    geo.spec
                        .parts
                        .iter()
                        .map(|p| p.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            })?;
        let stream = key.stream_seed(self.config.dataset.seed);
        let draws = self.sequence_draws(key.condition, stream);
        let resized;
        let geo = if draws.object_scale == 1.0 {
            geo
        } else {
            resized = geo.scaled(draws.object_scale);
            &resized
        };
        let accepted = self
            .search(geo, part_index, key.condition, stream, &draws)
            .with_context(|| format!("planning {}", key.id()))?;
        self.build_plan(key, geo, part_index, part, stream, &draws, accepted)
    }

    /// The lens (`[randomize.fov]`, or `unseen_look`'s own, and the
    /// principal point) and the approach levers of a sequence, each from its
    /// own sub-stream.
    fn sequence_draws(&self, condition: Condition, stream: u64) -> SequenceDraws {
        let r = &self.levers;
        let (intrinsics, fov_scale, principal_point_shift) = self.lens(condition, stream);
        SequenceDraws {
            intrinsics,
            fov_scale,
            principal_point_shift,
            approach: randomize::approach(r, self.config.plan.trajectory.standoff_m, stream),
            object_scale: randomize::object_scale(r, stream),
        }
    }

    /// The lens of a sequence drawn from `stream`: its intrinsics, lens
    /// factor and principal-point shift.
    fn lens(&self, condition: Condition, stream: u64) -> (CameraIntrinsics, f64, [f64; 2]) {
        let r = &self.levers;
        let fov = if condition == Condition::UnseenLook {
            Some(self.config.appearance.unseen_look.fov_scale)
        } else {
            r.fov.enabled.then_some(r.fov.scale)
        };
        let shift = r
            .principal_point
            .enabled
            .then_some(r.principal_point.max_shift);
        let base = self.config.plan.camera.intrinsics();
        randomize::intrinsics(&base, fov, shift, stream)
    }

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
        if matches!(s.path, super::trajectory::Path::Straight { .. }) {
            pts.pop(); // the straight segment runs start -> target directly
        }
        pts.push(c.target);
        pts.iter().map(|p| c.placement.to_object(p)).collect()
    }

    fn search(
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
        bail!(
            "object {}, part {}: no valid {condition} approach in {max} attempts ({})",
            geo.spec.id,
            geo.spec.parts[part_index].name,
            reasons.join("; ")
        )
    }

    #[allow(clippy::too_many_arguments)]
    fn build_plan(
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
        let head = self.head_camera(key, geo, &c.placement, stream);
        let mut elbows = Vec::new();
        if let Some(h) = &head {
            for f in &mut frames {
                f.head_camera = Some(h.pose());
                let e = super::head_camera::elbow(&h.shoulder(), &f.camera.position.into());
                elbows.push([e.x, e.y, e.z]);
            }
        }

        let mut sampled = sampled_record(&accepted, draws, part, &wrist);
        let mut put = |k: &str, v: serde_json::Value| {
            sampled.insert(k.to_string(), v);
        };
        for (k, v) in head.iter().flat_map(|h| h.sampled()) {
            put(k, v);
        }
        if head.is_some() {
            put("head_elbows", json!(elbows));
        }
        if let Some(world) = &self.config.dataset.held_out {
            put("held_out", json!(world));
        }

        let (distractors, rejected) = self.distractors(geo, c, s, stream);
        if self.levers.distractors.enabled {
            put("distractor_count", json!(distractors.len()));
            put("distractor_rejected_draws", json!(rejected));
        }
        let colors = randomize::color_range(
            &self.levers.object_color,
            geo.spec.color.as_ref(),
            crate::appearance::default_object_hsv(&geo.spec.id),
        );
        let appearance = Some(randomize::sequence_appearance(
            &self.config.appearance,
            &self.levers,
            key.condition,
            stream,
            &colors,
            c.placement.position.into(),
            &self.images,
        ));
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
            object: ObjectPlacement {
                pose: Pose {
                    position: c.placement.position.into(),
                    rotation_wxyz: wrist::to_wxyz(&c.placement.rotation),
                },
                yaw_deg: c.placement.yaw.to_degrees(),
                upside_down: c.placement.upside_down,
                on_table_border: c.placement.on_border,
                scale: draws.object_scale,
            },
            target: c.target.into(),
            other_end: c.other_end.into(),
            frames,
            sampled,
            appearance,
            distractors,
        })
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
        let keepout = super::distractors::Keepout {
            object_center: c.placement.to_world(&geo.sphere_center),
            object_radius: geo.sphere_radius,
            path: &path,
            target: c.target,
        };
        super::distractors::sample(lever, &self.config.plan.scene, &keepout, stream)
    }
}

/// The `n` frames' camera poses and labels: the part's class, then
/// `no_grasp` for the tail.
fn frame_poses(
    traj: &super::TrajectoryConfig,
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
    if draws.object_scale != 1.0 {
        put("object_scale", json!(draws.object_scale));
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

impl Planner {
    /// The static head camera of a sequence, from its own sub-stream (None
    /// unless `plan.head_camera.enabled`).
    fn head_camera(
        &self,
        key: &SequenceKey,
        geo: &ObjectGeometry,
        placement: &Placement,
        stream: u64,
    ) -> Option<super::head_camera::HeadCamera> {
        let cfg = &self.config.plan;
        if !cfg.head_camera.enabled {
            return None;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(substream_seed(stream, "head_camera"));
        let center = placement.to_world(&geo.sphere_center);
        Some(super::head_camera::sample(
            &cfg.head_camera,
            &cfg.scene,
            key.condition,
            [placement.position.x, placement.position.y],
            &center,
            &mut rng,
        ))
    }
}
