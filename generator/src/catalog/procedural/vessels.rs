//! Open vessels: a hollow turned body, with a handle where the real
//! object has one.

use crate::catalog::mesh::TriMesh;
use crate::catalog::shapes::*;
use std::f64::consts::PI;

pub(super) fn mug(r: f64, h: f64, wall: f64, reach: f64) -> TriMesh {
    let bottom = wall * 1.5;
    let profile = [
        (0.0, 0.0),
        (r - 0.003, 0.0),
        (r, 0.003),
        (r, h),
        (r - wall, h),
        (r - wall, bottom + 0.004),
        (r - wall - 0.004, bottom),
        (0.0, bottom),
    ];
    let mut m = lathe(&profile, SEGMENTS * 2);
    // The handle: a C from near the rim out to `reach` beyond the wall and
    // back near the bottom, sunk 2 mm into the wall at both ends.
    let (zt, zb) = (h * 0.82, h * 0.25);
    let zc = (zt + zb) / 2.0;
    let rz = (zt - zb) / 2.0;
    let t = 0.006;
    let path: Vec<V3> = (0..=24)
        .map(|i| {
            let a = PI / 2.0 - PI * i as f64 / 24.0;
            let x = r - wall / 2.0 + (reach - t) * a.cos().max(0.0).powf(0.8);
            [x, 0.0, zc + rz * a.sin()]
        })
        .collect();
    let radii = vec![(t, 0.0075); path.len()];
    m.append(tube(&path, &radii, [0.0, 1.0, 0.0], false, 20));
    m
}

pub(super) fn pitcher(r: f64, h: f64, wall: f64, reach: f64) -> TriMesh {
    let top = r * 0.9;
    let mut profile = vec![(0.0, 0.0), (r * 0.93, 0.0), (r * 0.97, 0.004)];
    for i in 0..=10 {
        let t = i as f64 / 10.0;
        let rr = r * 0.97 + (r - r * 0.97) * (PI * t).sin() * (1.0 - t) + (top - r * 0.97) * t * t;
        profile.push((rr, 0.015 + t * (h - 0.015)));
    }
    for i in (0..=10).rev() {
        let t = i as f64 / 10.0;
        let rr = r * 0.97 + (r - r * 0.97) * (PI * t).sin() * (1.0 - t) + (top - r * 0.97) * t * t;
        let z = 0.015 + t * (h - 0.015);
        if z > wall * 2.0 + 0.01 {
            profile.push((rr - wall, z.min(h)));
        }
    }
    profile.push((r * 0.97 - wall - 0.004, wall * 2.0));
    profile.push((0.0, wall * 2.0));
    let mut m = lathe(&profile, SEGMENTS * 2);
    // Handle: an open loop from under the rim down the side.
    let (zt, zb) = (h * 0.88, h * 0.38);
    let path: Vec<V3> = (0..=28)
        .map(|i| {
            let u = i as f64 / 28.0;
            let a = PI / 2.0 - PI * u;
            let wall_r = top + (r - top) * (1.0 - (u * 0.8));
            let x = wall_r - wall + (reach - 0.01) * a.cos().max(0.0).powf(0.6);
            [x, 0.0, (zt + zb) / 2.0 + (zt - zb) / 2.0 * a.sin()]
        })
        .collect();
    let radii = vec![(0.007, 0.012); path.len()];
    m.append(tube(&path, &radii, [0.0, 1.0, 0.0], false, 20));
    // Spout: a short lip leaning out of the rim on -X.
    let spout = [
        [-top + wall * 2.0, -0.025],
        [-top - 0.012, -0.012],
        [-top - 0.018, 0.0],
        [-top - 0.012, 0.012],
        [-top + wall * 2.0, 0.025],
    ];
    m.append(prism(&spout, h - 0.03, h - 0.004));
    m
}

pub(super) fn plate(r: f64, h: f64) -> TriMesh {
    let profile = [
        (0.0, 0.002),
        (r * 0.5, 0.002),
        (r * 0.52, 0.0),
        (r * 0.6, 0.0),
        (r * 0.63, 0.004),
        (r * 0.98, h * 0.82),
        (r, h * 0.93),
        (r * 0.985, h),
        (r * 0.96, h * 0.98),
        (r * 0.65, h * 0.33),
        (0.0, h * 0.26),
    ];
    lathe(&profile, SEGMENTS * 2)
}
