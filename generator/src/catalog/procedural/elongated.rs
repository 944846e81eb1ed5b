//! Long round bodies lying along X: a curved tube (banana) and a turned
//! pen body laid on its side (marker).

use crate::catalog::mesh::TriMesh;
use crate::catalog::shapes::*;

/// Length of the banana's stem along its axis.
const STEM_LENGTH: f64 = 0.022;

pub(super) fn banana(length: f64, bend: f64, radius: f64) -> TriMesh {
    // Circular arc with sagitta `bend`; the stem and the knob take the
    // rest of the length.
    let half = (length - STEM_LENGTH - 0.011) / 2.0;
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
    // Stem: a thin neck at -X that narrows out of the body, rises as it
    // leaves it and ends in a blunt cut, as a real banana's does.
    let last = path[0];
    // Along the body's end, turned part way back towards the long axis.
    let dir = {
        let d = [path[0][0] - path[1][0], path[0][1] - path[1][1], 0.0];
        let n = (d[0] * d[0] + d[1] * d[1]).sqrt();
        let d = [d[0] / n - 0.5, d[1] / n, 0.0];
        let n = (d[0] * d[0] + d[1] * d[1]).sqrt();
        [d[0] / n, d[1] / n, 0.0]
    };
    let steps = 8;
    let stem: Vec<V3> = (0..=steps)
        .map(|k| {
            let s = STEM_LENGTH * k as f64 / steps as f64;
            let rise = 0.25 * s * s / STEM_LENGTH;
            [last[0] + dir[0] * s, last[1] + dir[1] * s, last[2] + rise]
        })
        .collect();
    let stem_radii: Vec<(f64, f64)> = (0..=steps)
        .map(|k| {
            let u = k as f64 / steps as f64;
            let rr = radius * (0.45 - 0.25 * u.min(0.5) + 0.06 * (u - 0.85).max(0.0) / 0.15);
            (rr, rr)
        })
        .collect();
    let mut full_path: Vec<V3> = stem.iter().rev().copied().collect();
    let mut full_radii: Vec<(f64, f64)> = stem_radii.iter().rev().copied().collect();
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
