//! Procedural meshes of the built-in objects, sized from the real YCB
//! objects. Every kind builds its mesh from closed shells (`shapes`), then
//! moves it into the object frame (bottom centre of the bounding box at the
//! origin). Long objects lie along X.

use super::mesh::TriMesh;
use super::shapes::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Parameters of a built-in procedural shape (metres).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ProceduralShape {
    /// An axis-aligned box with slightly rounded vertical edges.
    Block { size: [f64; 3] },
    /// A cylinder standing on Z with a lip at the top (chips can).
    Can { radius: f64, height: f64, lip: f64 },
    /// A rounded-rectangle tin standing on Z (meat can).
    Tin { size: [f64; 3], corner: f64 },
    /// An ellipsoid resting on its lowest point (plum, baseball).
    Ellipsoid { size: [f64; 3] },
    /// A squeeze bottle with an elliptic body, a shoulder and a cap.
    Bottle {
        body: [f64; 3],
        cap_radius: f64,
        cap_height: f64,
    },
    /// A hollow cylinder with a bottom and a C-shaped handle on +X.
    Mug {
        radius: f64,
        height: f64,
        wall: f64,
        handle_reach: f64,
    },
    /// A hollow jug with a handle on +X and a spout on -X.
    Pitcher {
        radius: f64,
        height: f64,
        wall: f64,
        handle_reach: f64,
    },
    /// A plate with a raised rim.
    Plate { radius: f64, height: f64 },
    /// A curved tapered tube with a stem, bent towards +Y, along X.
    Banana { length: f64, bend: f64, radius: f64 },
    /// A handle along +X and a head (striking face and claw) across Y at -X.
    Hammer {
        length: f64,
        head_width: f64,
        thickness: f64,
    },
    /// Closed scissors: blades towards -X, two finger loops at +X.
    Scissors {
        length: f64,
        width: f64,
        thickness: f64,
    },
    /// A handle towards -X and a blade tilted up towards +X.
    Spatula {
        length: f64,
        blade_width: f64,
        height: f64,
    },
    /// A handle towards -X rising to its end and a bowl at +X.
    Spoon {
        length: f64,
        bowl_width: f64,
        height: f64,
    },
    /// A marker lying along X: a barrel, a cap at +X and a tapered end.
    Marker { length: f64, radius: f64 },
}

impl ProceduralShape {
    pub fn kind(&self) -> &'static str {
        match self {
            ProceduralShape::Block { .. } => "block",
            ProceduralShape::Can { .. } => "can",
            ProceduralShape::Tin { .. } => "tin",
            ProceduralShape::Ellipsoid { .. } => "ellipsoid",
            ProceduralShape::Bottle { .. } => "bottle",
            ProceduralShape::Mug { .. } => "mug",
            ProceduralShape::Pitcher { .. } => "pitcher",
            ProceduralShape::Plate { .. } => "plate",
            ProceduralShape::Banana { .. } => "banana",
            ProceduralShape::Hammer { .. } => "hammer",
            ProceduralShape::Scissors { .. } => "scissors",
            ProceduralShape::Spatula { .. } => "spatula",
            ProceduralShape::Spoon { .. } => "spoon",
            ProceduralShape::Marker { .. } => "marker",
        }
    }

    /// Every numeric parameter, with its name, for validation.
    pub fn parameters(&self) -> Vec<(&'static str, f64)> {
        use ProceduralShape::*;
        let v3 = |n: &'static str, s: &[f64; 3]| vec![(n, s[0]), (n, s[1]), (n, s[2])];
        match self {
            Block { size } | Ellipsoid { size } => v3("size", size),
            Can {
                radius,
                height,
                lip,
            } => vec![("radius", *radius), ("height", *height), ("lip", *lip)],
            Tin { size, corner } => [v3("size", size), vec![("corner", *corner)]].concat(),
            Bottle {
                body,
                cap_radius,
                cap_height,
            } => [
                v3("body", body),
                vec![("cap_radius", *cap_radius), ("cap_height", *cap_height)],
            ]
            .concat(),
            Mug {
                radius,
                height,
                wall,
                handle_reach,
            }
            | Pitcher {
                radius,
                height,
                wall,
                handle_reach,
            } => vec![
                ("radius", *radius),
                ("height", *height),
                ("wall", *wall),
                ("handle_reach", *handle_reach),
            ],
            Plate { radius, height } => vec![("radius", *radius), ("height", *height)],
            Banana {
                length,
                bend,
                radius,
            } => vec![("length", *length), ("bend", *bend), ("radius", *radius)],
            Hammer {
                length,
                head_width,
                thickness,
            } => vec![
                ("length", *length),
                ("head_width", *head_width),
                ("thickness", *thickness),
            ],
            Scissors {
                length,
                width,
                thickness,
            } => vec![
                ("length", *length),
                ("width", *width),
                ("thickness", *thickness),
            ],
            Spatula {
                length,
                blade_width,
                height,
            } => vec![
                ("length", *length),
                ("blade_width", *blade_width),
                ("height", *height),
            ],
            Spoon {
                length,
                bowl_width,
                height,
            } => vec![
                ("length", *length),
                ("bowl_width", *bowl_width),
                ("height", *height),
            ],
            Marker { length, radius } => vec![("length", *length), ("radius", *radius)],
        }
    }

    /// The mesh in the object frame.
    pub fn mesh(&self) -> TriMesh {
        use ProceduralShape::*;
        let m = match *self {
            Block { size } => tin(size, size[0].min(size[1]) * 0.04),
            Can {
                radius,
                height,
                lip,
            } => can(radius, height, lip),
            Tin { size, corner } => tin(size, corner),
            Ellipsoid { size } => ellipsoid([size[0] / 2.0, size[1] / 2.0, size[2] / 2.0], 32),
            Bottle {
                body,
                cap_radius,
                cap_height,
            } => bottle(body, cap_radius, cap_height),
            Mug {
                radius,
                height,
                wall,
                handle_reach,
            } => mug(radius, height, wall, handle_reach),
            Pitcher {
                radius,
                height,
                wall,
                handle_reach,
            } => pitcher(radius, height, wall, handle_reach),
            Plate { radius, height } => plate(radius, height),
            Banana {
                length,
                bend,
                radius,
            } => banana(length, bend, radius),
            Hammer {
                length,
                head_width,
                thickness,
            } => hammer(length, head_width, thickness),
            Scissors {
                length,
                width,
                thickness,
            } => scissors(length, width, thickness),
            Spatula {
                length,
                blade_width,
                height,
            } => spatula(length, blade_width, height),
            Spoon {
                length,
                bowl_width,
                height,
            } => spoon(length, bowl_width, height),
            Marker { length, radius } => marker(length, radius),
        };
        m.recentred()
    }
}

fn can(r: f64, h: f64, lip: f64) -> TriMesh {
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

fn tin(size: [f64; 3], corner: f64) -> TriMesh {
    let outline = rounded_rect(size[0], size[1], corner, 6);
    prism(&outline, 0.0, size[2])
}

fn bottle(body: [f64; 3], cap_r: f64, cap_h: f64) -> TriMesh {
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

fn mug(r: f64, h: f64, wall: f64, reach: f64) -> TriMesh {
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

fn pitcher(r: f64, h: f64, wall: f64, reach: f64) -> TriMesh {
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

fn plate(r: f64, h: f64) -> TriMesh {
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

fn banana(length: f64, bend: f64, radius: f64) -> TriMesh {
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

fn hammer(length: f64, head_width: f64, thickness: f64) -> TriMesh {
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

fn scissors(length: f64, width: f64, t: f64) -> TriMesh {
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

fn spatula(length: f64, blade_w: f64, height: f64) -> TriMesh {
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

fn spoon(length: f64, bowl_w: f64, height: f64) -> TriMesh {
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

fn marker(length: f64, r: f64) -> TriMesh {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lathe_cylinder_has_the_analytic_volume() {
        let (r, h) = (0.03, 0.1);
        let m = lathe(&[(0.0, 0.0), (r, 0.0), (r, h), (0.0, h)], 256);
        let exact = PI * r * r * h;
        assert!((m.signed_volume() - exact).abs() / exact < 1e-3);
    }

    #[test]
    fn closed_tube_torus_faces_outward() {
        let path: Vec<V3> = (0..64)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 64.0;
                [0.05 * a.cos(), 0.05 * a.sin(), 0.0]
            })
            .collect();
        let m = tube(&path, &vec![(0.01, 0.01); 64], [0.0, 0.0, 1.0], true, 32);
        let exact = 2.0 * PI * PI * 0.05 * 0.01 * 0.01;
        assert!((m.signed_volume() - exact).abs() / exact < 0.01);
    }

    #[test]
    fn prism_box_volume() {
        let m = cuboid([0.1, 0.2, 0.3]);
        assert!((m.signed_volume() - 0.006).abs() < 1e-12);
    }
}
