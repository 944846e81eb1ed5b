//! Closed containers that stand on Z: turned (lathed) profiles and
//! extruded outlines.

use crate::catalog::mesh::TriMesh;
use crate::catalog::shapes::*;
use std::f64::consts::PI;

pub(super) fn can(r: f64, h: f64, lip: f64) -> TriMesh {
    let b = 0.004_f64.min(h / 10.0);
    let profile = [
        (0.0, 0.0),
        (r - b, 0.0),
        (r, b),
        (r, h - 2.0 * b),
        (r + lip, h - 1.5 * b),
        (r + lip, h),
        (r - b, h),
        (r - b, h - b / 2.0),
        (0.0, h - b / 2.0),
    ];
    lathe(&profile, SEGMENTS)
}

pub(super) fn tin(size: [f64; 3], corner: f64) -> TriMesh {
    let outline = rounded_rect(size[0], size[1], corner, 6);
    prism(&outline, 0.0, size[2])
}

pub(super) fn bottle(body: [f64; 3], cap_r: f64, cap_h: f64) -> TriMesh {
    // Unit-radius profile scaled into an elliptic body; the cap is round.
    let (a, b, h) = (body[0] / 2.0, body[1] / 2.0, body[2]);
    let shoulder = h * 0.78;
    let neck = cap_r * 1.25;
    let mut profile = vec![(0.0, 0.0), (0.93, 0.0), (1.0, 0.03 * h)];
    for i in 0..=8 {
        let t = i as f64 / 8.0;
        let r = 1.0 + 0.02 * (PI * t).sin();
        profile.push((r, 0.06 * h + t * (shoulder - 0.06 * h)));
    }
    for i in 1..=6 {
        let t = i as f64 / 6.0;
        let r = 1.0 - (1.0 - neck / a.min(b)) * (t * PI / 2.0).sin();
        profile.push((r, shoulder + t * (h - shoulder)));
    }
    profile.push((0.0, h));
    let mut m = lathe(&profile, SEGMENTS).scaled([a, b, 1.0]);
    let cap = [
        (0.0, h - 0.002),
        (cap_r, h - 0.002),
        (cap_r, h + cap_h * 0.55),
        (cap_r * 0.45, h + cap_h * 0.8),
        (cap_r * 0.25, h + cap_h),
        (0.0, h + cap_h),
    ];
    m.append(lathe(&cap, SEGMENTS / 2));
    m
}
