//! Flat or handled tools that lie along X on the table.

use crate::catalog::mesh::TriMesh;
use crate::catalog::shapes::*;
use std::f64::consts::PI;

pub(super) fn hammer(length: f64, head_width: f64, thickness: f64) -> TriMesh {
    let hr = thickness / 2.0;
    let head_x = -length / 2.0 + hr * 1.1;
    // Handle: an oval rod from inside the head to the +X end, widening a bit.
    let n = 12;
    let path: Vec<V3> = (0..=n)
        .map(|i| {
            let x = head_x + (length / 2.0 - hr * 0.5 - head_x) * i as f64 / n as f64;
            [x, 0.0, hr]
        })
        .collect();
    let radii: Vec<(f64, f64)> = (0..=n)
        .map(|i| {
            let u = i as f64 / n as f64;
            let w = hr * (0.85 + 0.25 * u);
            (w, hr * (0.7 + 0.1 * u))
        })
        .collect();
    let mut m = tube(&path, &radii, [0.0, 0.0, 1.0], false, 20);
    let end = *path.last().expect("path");
    m.append(ellipsoid([hr * 0.5, radii[n].0, radii[n].1], 10).translated(end));
    // Head: a round striking part towards -Y, a flat tapered claw towards +Y.
    let face_len = head_width * 0.5;
    let strike = [
        (0.0, 0.0),
        (hr * 0.95, 0.0),
        (hr, 0.004),
        (hr * 0.85, face_len * 0.75),
        (hr * 0.9, face_len - 0.004),
        (hr * 0.85, face_len),
        (0.0, face_len),
    ];
    let strike = lathe(&strike, 24)
        .rotated([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
        .translated([head_x, 0.004, hr]);
    m.append(strike);
    let claw_len = head_width * 0.5;
    let claw: Vec<[f64; 2]> = vec![
        [head_x - hr * 0.9, 0.0],
        [head_x - hr * 0.8, -claw_len * 0.5],
        [head_x - hr * 0.3, -claw_len * 0.95],
        [head_x + hr * 0.2, -claw_len],
        [head_x + hr * 0.6, -claw_len * 0.6],
        [head_x + hr * 0.9, 0.0],
    ];
    m.append(prism(&claw, hr - hr * 0.6, hr + hr * 0.6));
    m
}

pub(super) fn scissors(length: f64, width: f64, t: f64) -> TriMesh {
    let pivot_x = length * 0.05;
    let tip = -length / 2.0;
    let zc = t / 2.0;
    let blade_t = t * 0.45;
    // Closed blades: one tapered prism from the pivot to the tip.
    let blade = [
        [tip, 0.0],
        [tip + 0.01, -0.003],
        [pivot_x, -0.008],
        [pivot_x + 0.012, -0.006],
        [pivot_x + 0.012, 0.006],
        [pivot_x, 0.008],
        [tip + 0.01, 0.003],
    ];
    let mut m = prism(&blade, zc - blade_t / 2.0, zc + blade_t / 2.0);
    // Pivot screw.
    m.append(
        lathe(
            &[(0.0, 0.0), (0.005, 0.0), (0.005, t * 0.9), (0.0, t * 0.9)],
            16,
        )
        .translated([pivot_x, 0.0, 0.0]),
    );
    // Finger loops: elliptic rings left and right of the axis.
    let loop_end = length / 2.0;
    let ring_r = t / 2.0;
    let (ax, ay) = (
        (loop_end - pivot_x - 0.018) / 2.0 - ring_r,
        width / 4.0 - ring_r,
    );
    for side in [-1.0, 1.0] {
        let c = [loop_end - ring_r - ax, side * (width / 2.0 - ring_r - ay)];
        let path: Vec<V3> = (0..36)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 36.0;
                [c[0] + ax * a.cos(), c[1] + ay * a.sin(), zc]
            })
            .collect();
        let radii = vec![(ring_r * 0.9, ring_r); path.len()];
        m.append(tube(&path, &radii, [0.0, 0.0, 1.0], true, 12));
        // Shank from the pivot to the ring.
        let shank = [
            [pivot_x + 0.005, side * 0.004],
            [c[0] - ax + 0.002, c[1] - side * 0.004],
        ];
        let path = vec![
            [shank[0][0], shank[0][1], zc],
            [
                (shank[0][0] + shank[1][0]) / 2.0,
                (shank[0][1] + shank[1][1]) / 2.0,
                zc,
            ],
            [shank[1][0], shank[1][1], zc],
        ];
        m.append(tube(
            &path,
            &[(ring_r * 0.8, ring_r * 0.8); 3],
            [0.0, 0.0, 1.0],
            false,
            12,
        ));
    }
    m
}

pub(super) fn spatula(length: f64, blade_w: f64, height: f64) -> TriMesh {
    let x0 = -length / 2.0;
    let blade_len = length * 0.33;
    let neck_x = length / 2.0 - blade_len;
    // Handle: a flat oval rod, thickest at its end, rising to the neck.
    let n = 16;
    let mut path = Vec::new();
    let mut radii = Vec::new();
    for i in 0..=n {
        let u = i as f64 / n as f64;
        let x = x0 + 0.006 + u * (neck_x - x0 - 0.006);
        let z = 0.009 + 0.008 * (PI * u).sin() - 0.004 * u;
        path.push([x, 0.0, z]);
        let w = 0.014 - 0.006 * u;
        radii.push((w, 0.009 - 0.005 * u));
    }
    let mut m = tube(&path, &radii, [0.0, 0.0, 1.0], false, 20);
    m.append(ellipsoid([0.006, 0.014, 0.009], 10).translated(path[0]));
    // Blade: a thin rounded plate tilted up towards +X.
    let outline = rounded_rect(blade_len, blade_w, 0.012, 6);
    let tilt = ((height - 0.004) / blade_len).atan();
    let blade = prism(&outline, -0.0015, 0.0015)
        .translated([blade_len / 2.0, 0.0, 0.0])
        .rotated(rot_y(-tilt))
        .translated([neck_x - 0.004, 0.0, 0.003]);
    m.append(blade);
    m
}

pub(super) fn spoon(length: f64, bowl_w: f64, height: f64) -> TriMesh {
    let bowl_len = length * 0.33;
    let bowl_c = length / 2.0 - bowl_len / 2.0;
    let bowl_h = height * 0.4;
    // Bowl: a shallow half-ellipsoid cup (outer shell) with a flat rim top.
    let mut profile = Vec::new();
    for i in 0..=10 {
        let a = PI / 2.0 * i as f64 / 10.0;
        profile.push((a.sin(), bowl_h * (1.0 - a.cos())));
    }
    profile.push((0.92, bowl_h * 1.05));
    for i in (0..=8).rev() {
        let a = PI / 2.0 * i as f64 / 8.0;
        profile.push((0.9 * a.sin(), bowl_h * (1.05 - 0.8 * a.cos())));
    }
    profile.dedup();
    let mut m = lathe(&profile, SEGMENTS)
        .scaled([bowl_len / 2.0, bowl_w / 2.0, 1.0])
        .translated([bowl_c, 0.0, 0.0]);
    // Handle: a flat strip rising from the bowl to its end at -X.
    let n = 16;
    let x1 = bowl_c - bowl_len / 2.0 + 0.004;
    let x0 = -length / 2.0 + 0.008;
    let mut path = Vec::new();
    let mut radii = Vec::new();
    for i in 0..=n {
        let u = i as f64 / n as f64;
        let x = x1 + u * (x0 - x1);
        let z = bowl_h * 0.9 + (height - 0.003 - bowl_h * 0.9) * u.powf(1.3);
        path.push([x, 0.0, z]);
        let w = 0.0035 + 0.0045 * u.powf(0.7);
        radii.push((w, 0.0018));
    }
    m.append(tube(&path, &radii, [0.0, 0.0, 1.0], false, 16));
    let end = *path.last().expect("path");
    m.append(ellipsoid([0.008, 0.008, 0.0018], 10).translated(end));
    m
}
