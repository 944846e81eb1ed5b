//! The wrist's two rotations of one sequence (pronation-supination and
//! flexion-extension) and the camera orientation they give along the path.

use super::schedule::WristSchedule;
use super::{look_at, RollRule};
use crate::catalog::Pronation;
use crate::plan::conditions::PathSample;
use crate::plan::trajectory::min_jerk;
use crate::plan::TrajectoryConfig;
use grasp_schema::plan::substream_seed;
use nalgebra::{UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The wrist's two rotations of a sequence: pronation-supination turns the
/// camera's X onto the target box's X axis, flexion-extension pitches it
/// towards the part's other end; the schedule says how much of each is
/// done at each moment.
pub struct WristAngles {
    pub schedule: WristSchedule,
    /// Pronation-supination angle (radians, about the view direction).
    pub ps_angle: f64,
    /// Flexion-extension angle (radians, about the camera's X).
    pub fe_angle: f64,
    /// The approach direction at the end of the path.
    pub final_dir: Vector3<f64>,
    /// The path's end point.
    pub end: Vector3<f64>,
}

impl WristAngles {
    /// `sample` is the accepted path, `target` and `other_end` the ends of
    /// the part's box along its approach axis, `box_x` the box's X axis in
    /// the world, `pronation` the part's rule; `stream` is the sequence's.
    pub fn new(
        traj: &TrajectoryConfig,
        s: &PathSample,
        target: Vector3<f64>,
        other_end: Vector3<f64>,
        box_x: Vector3<f64>,
        pronation: Pronation,
        stream: u64,
    ) -> WristAngles {
        let mut wrist_rng = ChaCha8Rng::seed_from_u64(substream_seed(stream, "wrist"));
        let schedule = WristSchedule::sample(traj, s.approach_tau, &mut wrist_rng);
        let end = s.path.end();
        let final_dir = (target - end)
            .try_normalize(1e-12)
            .unwrap_or_else(|| (target - s.path.position(1.0 - 1e-6)).normalize());
        // Pronation-supination: turn the camera's X onto the box's X axis.
        let q_end = look_toward(target, final_dir, &end);
        let ps_angle = match pronation {
            Pronation::None => None,
            rule => {
                super::signed_angle_about(&final_dir, &super::right_axis(&q_end), &box_x).map(|a| {
                    super::wrap_roll(
                        a,
                        if rule == Pronation::Supination {
                            RollRule::Supination
                        } else {
                            RollRule::Shortest
                        },
                    )
                })
            }
        }
        .unwrap_or(0.0);
        // Flexion-extension: pitch about the camera's X towards the other end.
        let q_end_ps = super::roll(&q_end, ps_angle * schedule.pronation_fraction(1.0));
        let fe_angle = super::signed_angle_about(
            &super::right_axis(&q_end_ps),
            &super::view_direction(&q_end_ps),
            &(other_end - end),
        )
        .unwrap_or(0.0);
        WristAngles {
            schedule,
            ps_angle,
            fe_angle,
            final_dir,
            end,
        }
    }

    /// The camera's orientation at `position` and normalised time `tau`:
    /// looking at the target, risen from the floor-facing start, rolled and
    /// pitched by the executed fractions of the wrist angles.
    pub fn camera_rotation(
        &self,
        target: Vector3<f64>,
        sample: &PathSample,
        position: &Vector3<f64>,
        tau: f64,
    ) -> UnitQuaternion<f64> {
        let (up, forward) = (Vector3::z(), Vector3::x());
        let mut q = look_toward(target, self.final_dir, position);
        if let Some(t1) = sample.rise_until.filter(|t1| tau < *t1) {
            let q_down = look_at(&-up, &up, &forward);
            q = super::slerp(&q_down, &q, min_jerk(tau / t1));
        }
        super::pitch(
            &super::roll(&q, self.ps_angle * self.schedule.pronation_fraction(tau)),
            self.fe_angle * self.schedule.flexion_fraction(tau),
        )
    }
}

/// The camera at `position` looking at `target` (along `final_dir` when it
/// is already there).
pub fn look_toward(
    target: Vector3<f64>,
    final_dir: Vector3<f64>,
    position: &Vector3<f64>,
) -> UnitQuaternion<f64> {
    let d = target - position;
    let d = if d.norm() > 1e-9 { d } else { final_dir };
    look_at(&d, &Vector3::z(), &Vector3::x())
}
