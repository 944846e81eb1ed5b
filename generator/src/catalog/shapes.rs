//! Mesh building blocks for the procedural objects: surfaces of revolution,
//! swept tubes, extruded polygons and ellipsoids. Each returns one closed
//! shell with outward-facing triangles; an object is a union of shells.

use super::mesh::TriMesh;
use std::f64::consts::{PI, TAU};

pub type V3 = [f64; 3];

/// Angular resolution of round parts.
pub const SEGMENTS: usize = 48;

impl TriMesh {
    /// Appends another mesh's triangles.
    pub fn append(&mut self, other: TriMesh) {
        let base = self.vertices.len() as u32;
        self.vertices.extend(other.vertices);
        self.faces
            .extend(other.faces.into_iter().map(|f| f.map(|i| i + base)));
    }

    pub fn translated(mut self, t: V3) -> TriMesh {
        for v in &mut self.vertices {
            *v = [v[0] + t[0], v[1] + t[1], v[2] + t[2]];
        }
        self
    }

    /// Applies `v -> r * v` with `r` given by rows.
    pub fn rotated(mut self, r: [[f64; 3]; 3]) -> TriMesh {
        for v in &mut self.vertices {
            *v = [0, 1, 2].map(|i| r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2]);
        }
        self
    }

    pub fn scaled(mut self, s: V3) -> TriMesh {
        for v in &mut self.vertices {
            *v = [v[0] * s[0], v[1] * s[1], v[2] * s[2]];
        }
        if s[0] * s[1] * s[2] < 0.0 {
            self.flip();
        }
        self
    }

    pub fn flip(&mut self) {
        for f in &mut self.faces {
            f.swap(1, 2);
        }
    }

    /// Signed volume (positive when the triangles face outward).
    pub fn signed_volume(&self) -> f64 {
        self.faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| self.vertices[i as usize]);
                dot(a, cross(b, c)) / 6.0
            })
            .sum()
    }

    /// Axis-aligned bounds (min, max); zeros for an empty mesh.
    pub fn bounds(&self) -> (V3, V3) {
        if self.vertices.is_empty() {
            return ([0.0; 3], [0.0; 3]);
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for v in &self.vertices {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        (lo, hi)
    }

    /// Moves the mesh so the centre of its bounding box's bottom face is at
    /// the origin (the object-frame convention).
    pub fn recentred(self) -> TriMesh {
        let (lo, hi) = self.bounds();
        let t = [-(lo[0] + hi[0]) / 2.0, -(lo[1] + hi[1]) / 2.0, -lo[2]];
        self.translated(t)
    }

    /// Flips the shell if it faces inward.
    fn outward(mut self) -> TriMesh {
        if self.signed_volume() < 0.0 {
            self.flip();
        }
        self
    }
}

pub fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: V3) -> V3 {
    let n = dot(a, a).sqrt();
    if n == 0.0 {
        a
    } else {
        [a[0] / n, a[1] / n, a[2] / n]
    }
}

/// Rotation about Y by `a` radians, as rows.
pub fn rot_y(a: f64) -> [[f64; 3]; 3] {
    let (s, c) = a.sin_cos();
    [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
}

/// Surface of revolution about Z. `profile` is (radius, z), running from a
/// point on the axis to a point on the axis, counter-clockwise in the
/// (r, z) half-plane (outward along the bottom, inward along the top).
pub fn lathe(profile: &[(f64, f64)], segments: usize) -> TriMesh {
    assert!(profile.len() >= 3, "a lathe profile needs 3 points");
    let n = profile.len();
    let mut m = TriMesh::default();
    let bottom = push(&mut m, [0.0, 0.0, profile[0].1]);
    let ring_start = m.vertices.len() as u32;
    for &(r, z) in &profile[1..n - 1] {
        for j in 0..segments {
            let phi = TAU * j as f64 / segments as f64;
            m.vertices.push([r * phi.cos(), r * phi.sin(), z]);
        }
    }
    let top = push(&mut m, [0.0, 0.0, profile[n - 1].1]);
    let s = segments as u32;
    let at = |ring: usize, j: u32| ring_start + ring as u32 * s + j % s;
    for j in 0..s {
        m.faces.push([bottom, at(0, j + 1), at(0, j)]);
        m.faces.push([top, at(n - 3, j), at(n - 3, j + 1)]);
    }
    for ring in 0..n - 3 {
        for j in 0..s {
            let (a, b) = (at(ring, j), at(ring, j + 1));
            let (c, d) = (at(ring + 1, j + 1), at(ring + 1, j));
            m.faces.push([a, b, c]);
            m.faces.push([a, c, d]);
        }
    }
    m.outward()
}

fn push(m: &mut TriMesh, v: V3) -> u32 {
    m.vertices.push(v);
    m.vertices.len() as u32 - 1
}

/// A closed ellipsoid with semi-axes `r`, centred at the origin.
pub fn ellipsoid(r: V3, rings: usize) -> TriMesh {
    let profile: Vec<(f64, f64)> = (0..=rings)
        .map(|i| {
            let t = PI * i as f64 / rings as f64;
            (t.sin(), -t.cos())
        })
        .collect();
    lathe(&profile, 2 * rings).scaled(r)
}

/// A tube swept along `path` with an elliptical cross-section (half-widths
/// `(a, b)` per path point; `b` lies along `up` projected off the tangent).
/// Open paths are capped; `closed` joins the last point back to the first.
pub fn tube(path: &[V3], radii: &[(f64, f64)], up: V3, closed: bool, sides: usize) -> TriMesh {
    assert_eq!(path.len(), radii.len());
    let n = path.len();
    let mut m = TriMesh::default();
    for i in 0..n {
        let prev = if i == 0 {
            if closed {
                path[n - 1]
            } else {
                path[0]
            }
        } else {
            path[i - 1]
        };
        let next = if i == n - 1 {
            if closed {
                path[0]
            } else {
                path[n - 1]
            }
        } else {
            path[i + 1]
        };
        let t = norm(sub(next, prev));
        let mut v = sub(up, scale(t, dot(up, t)));
        if dot(v, v) < 1e-12 {
            v = cross(t, [1.0, 0.0, 0.0]);
        }
        let v = norm(v);
        let u = cross(v, t);
        let (a, b) = radii[i];
        for j in 0..sides {
            let phi = TAU * j as f64 / sides as f64;
            let (s, c) = phi.sin_cos();
            m.vertices
                .push([0, 1, 2].map(|k| path[i][k] + a * c * u[k] + b * s * v[k]));
        }
    }
    let s = sides as u32;
    let at = |i: usize, j: u32| (i as u32) * s + j % s;
    let segs = if closed { n } else { n - 1 };
    for i in 0..segs {
        let i2 = (i + 1) % n;
        for j in 0..s {
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i2, j + 1), at(i2, j));
            m.faces.push([a, b, c]);
            m.faces.push([a, c, d]);
        }
    }
    if !closed {
        let c0 = push(&mut m, path[0]);
        let c1 = push(&mut m, path[n - 1]);
        for j in 0..s {
            m.faces.push([c0, at(0, j + 1), at(0, j)]);
            m.faces.push([c1, at(n - 1, j), at(n - 1, j + 1)]);
        }
    }
    m.outward()
}

fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// A star-shaped polygon (counter-clockwise, in XY) extruded from `z0` to `z1`.
pub fn prism(polygon: &[[f64; 2]], z0: f64, z1: f64) -> TriMesh {
    let n = polygon.len();
    let cx = polygon.iter().map(|p| p[0]).sum::<f64>() / n as f64;
    let cy = polygon.iter().map(|p| p[1]).sum::<f64>() / n as f64;
    let mut m = TriMesh::default();
    for z in [z0, z1] {
        for p in polygon {
            m.vertices.push([p[0], p[1], z]);
        }
    }
    let b = push(&mut m, [cx, cy, z0]);
    let t = push(&mut m, [cx, cy, z1]);
    let n32 = n as u32;
    for i in 0..n32 {
        let j = (i + 1) % n32;
        m.faces.push([b, j, i]);
        m.faces.push([t, n32 + i, n32 + j]);
        m.faces.push([i, j, n32 + j]);
        m.faces.push([i, n32 + j, n32 + i]);
    }
    m.outward()
}

/// A rounded rectangle of full size (w, h) and corner radius r, CCW.
pub fn rounded_rect(w: f64, h: f64, r: f64, corner_segments: usize) -> Vec<[f64; 2]> {
    let r = r.min(w / 2.0).min(h / 2.0);
    let centres = [
        (w / 2.0 - r, h / 2.0 - r, 0.0),
        (-w / 2.0 + r, h / 2.0 - r, PI / 2.0),
        (-w / 2.0 + r, -h / 2.0 + r, PI),
        (w / 2.0 - r, -h / 2.0 + r, 1.5 * PI),
    ];
    let mut pts = Vec::new();
    for (cx, cy, a0) in centres {
        for k in 0..=corner_segments {
            let a = a0 + PI / 2.0 * k as f64 / corner_segments as f64;
            pts.push([cx + r * a.cos(), cy + r * a.sin()]);
        }
    }
    pts
}

/// An axis-aligned box of full size `s` centred at the origin.
pub fn cuboid(s: V3) -> TriMesh {
    let poly = [
        [-s[0] / 2.0, -s[1] / 2.0],
        [s[0] / 2.0, -s[1] / 2.0],
        [s[0] / 2.0, s[1] / 2.0],
        [-s[0] / 2.0, s[1] / 2.0],
    ];
    prism(&poly, -s[2] / 2.0, s[2] / 2.0)
}

/// Points on a circular arc in the XY plane.
pub fn arc(centre: [f64; 2], radius: f64, a0: f64, a1: f64, n: usize) -> Vec<[f64; 2]> {
    (0..=n)
        .map(|i| {
            let a = a0 + (a1 - a0) * i as f64 / n as f64;
            [centre[0] + radius * a.cos(), centre[1] + radius * a.sin()]
        })
        .collect()
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
