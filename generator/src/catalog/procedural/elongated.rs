//! Long round bodies lying along X: a curved tube (banana) and a turned
//! pen body laid on its side (marker).

use crate::catalog::mesh::TriMesh;
use crate::catalog::shapes::*;

pub(super) fn banana(length: f64, bend: f64, radius: f64) -> TriMesh {
    // Circular arc with chord `length - 2 radius` and sagitta `bend`.
    let half = (length - 0.021) / 2.0;
    let rc = (half * half + bend * bend) / (2.0 * bend);
    let theta = (half / rc).asin();
    let n = 40;
    let mut path = Vec::new();
    let mut radii = Vec::new();
    for i in 0..=n {
        let u = -1.0 + 2.0 * i as f64 / n as f64;
        let phi = u * theta;
        let rr = radius * (1.0 - 0.55 * u.abs().powf(2.2));
        // The ends curl up off the table.
        let z = radius + 0.35 * radius * u * u;
        path.push([rc * phi.sin(), rc * phi.cos() - rc, z]);
        radii.push((rr, rr * 0.95));
    }
    // Stem: a short thin continuation at -X.
    let last = path[0];
    let dir = {
        let d = [path[0][0] - path[1][0], path[0][1] - path[1][1], 0.0];
        let n = (d[0] * d[0] + d[1] * d[1]).sqrt();
        [d[0] / n, d[1] / n, 0.0]
    };
    let stem_r = radius * 0.3;
    let stem: Vec<V3> = (0..=4)
        .map(|k| {
            let s = 0.004 * k as f64;
            [
                last[0] + dir[0] * s,
                last[1] + dir[1] * s,
                last[2] + 0.2 * s,
            ]
        })
        .collect();
    let mut full_path: Vec<V3> = stem.iter().rev().copied().collect();
    let mut full_radii = vec![(stem_r, stem_r); stem.len()];
    full_path.extend(path.iter().skip(1));
    full_radii.extend(radii.iter().skip(1));
    let mut m = tube(&full_path, &full_radii, [0.0, 0.0, 1.0], false, 16);
    // Blossom end: a small knob at +X.
    let end = *path.last().expect("path");
    m.append(ellipsoid([radius * 0.3; 3], 8).translated(end));
    m
}

pub(super) fn marker(length: f64, r: f64) -> TriMesh {
    let cap = length * 0.3;
    let profile = [
        (0.0, 0.0),
        (r * 0.35, 0.0),
        (r * 0.45, 0.006),
        (r * 0.85, 0.012),
        (r * 0.9, 0.016),
        (r, 0.02),
        (r, length - cap),
        (r * 1.06, length - cap + 0.001),
        (r * 1.06, length - 0.004),
        (r * 0.9, length - 0.0005),
        (r * 0.7, length),
        (0.0, length),
    ];
    // Built along Z, laid along X (tip towards -X), resting on the table.
    lathe(&profile, 32)
        .rotated([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
        .translated([-length / 2.0, 0.0, r * 1.06])
}
