//! MeshQuery against analytic answers on a cube and a sphere.

use generator::catalog::TriMesh;
use generator::geometry::{closest_on_triangle, MeshQuery, TriangleTree};

/// Axis-aligned cube [-h, h]^3, outward-facing triangles.
fn cube(h: f64) -> TriMesh {
    let vertices = (0..8)
        .map(|i| {
            [
                if i & 1 == 0 { -h } else { h },
                if i & 2 == 0 { -h } else { h },
                if i & 4 == 0 { -h } else { h },
            ]
        })
        .collect();
    let faces = vec![
        [0, 2, 1],
        [1, 2, 3], // z = -h
        [4, 5, 6],
        [5, 7, 6], // z = +h
        [0, 1, 4],
        [1, 5, 4], // y = -h
        [2, 6, 3],
        [3, 6, 7], // y = +h
        [0, 4, 2],
        [2, 4, 6], // x = -h
        [1, 3, 5],
        [3, 7, 5], // x = +h
    ];
    TriMesh { vertices, faces }
}

/// UV sphere of radius r, closed at the poles.
fn sphere(r: f64, rings: u32, segments: u32) -> TriMesh {
    let mut vertices = vec![[0.0, 0.0, -r]];
    for i in 1..rings {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = std::f64::consts::TAU * j as f64 / segments as f64;
            vertices.push([
                r * theta.sin() * phi.cos(),
                r * theta.sin() * phi.sin(),
                -r * theta.cos(),
            ]);
        }
    }
    vertices.push([0.0, 0.0, r]);
    let top = vertices.len() as u32 - 1;
    let ring = |i: u32, j: u32| 1 + (i - 1) * segments + j % segments;
    let mut faces = Vec::new();
    for j in 0..segments {
        faces.push([0, ring(1, j + 1), ring(1, j)]);
        faces.push([top, ring(rings - 1, j), ring(rings - 1, j + 1)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            faces.push([ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)]);
            faces.push([ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)]);
        }
    }
    TriMesh { vertices, faces }
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / n, v[1] / n, v[2] / n]
}

#[test]
fn cube_rays_hit_at_the_analytic_distance() {
    let q = MeshQuery::new(&cube(0.05)).unwrap();
    assert!(q.is_watertight());
    let origins = [
        [0.0, 0.0, 1.0],
        [0.01, -0.02, 0.3],
        [1.0, 0.02, 0.03],
        [0.0, 0.0, 0.0],   // from inside: exits through the +X face
        [0.0, 0.0, 1.0],   // pointing away: miss
        [0.2, 0.2, 1.0],   // passes beside the cube: miss
        [-0.5, 0.0, -0.5], // 45 degrees into the -X face's lower edge region
    ];
    let dirs = [
        [0.0, 0.0, -1.0],
        [0.0, 0.0, -1.0],
        [-1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
        unit([1.0, 0.0, 1.0]),
    ];
    let hits = q.first_hits(&origins, &dirs).unwrap();
    let want = [
        Some(0.95),
        Some(0.25),
        Some(0.95),
        Some(0.05),
        None,
        None,
        Some(0.45 * 2f64.sqrt()),
    ];
    for (i, (h, w)) in hits.iter().zip(want).enumerate() {
        match (h, w) {
            (Some(h), Some(w)) => assert!((h - w).abs() < 1e-5, "ray {i}: {h} vs {w}"),
            (None, None) => {}
            _ => panic!("ray {i}: got {h:?}, want {w:?}"),
        }
    }
}

#[test]
fn sphere_contains_and_closest_points_match_the_analytic_sphere() {
    let r = 0.04;
    let mesh = sphere(r, 48, 96);
    let q = MeshQuery::new(&mesh).unwrap();
    assert!(q.is_watertight());
    // A deterministic spread of points from the centre to well outside.
    let points: Vec<[f64; 3]> = (0..400)
        .map(|i| {
            let t = i as f64;
            let dir = unit([(t * 0.37).sin(), (t * 0.91).cos(), (t * 0.53).sin() + 0.1]);
            let rad = 0.1 * (i % 20) as f64 / 19.0;
            [dir[0] * rad, dir[1] * rad, dir[2] * rad]
        })
        .collect();
    let inside = q.contains(&points).unwrap();
    let closest = q.closest_points(&points).unwrap();
    // The polygon lies within r(1 - cos(pi/48)) of the true sphere.
    let tol = r * (1.0 - (std::f64::consts::PI / 48.0).cos()) + 1e-9;
    let mut checked_inside = 0;
    for (p, (is_in, (c, d))) in points.iter().zip(inside.iter().zip(&closest)) {
        let norm = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        if norm < r - tol {
            assert!(is_in, "{p:?} at {norm} should be inside");
            checked_inside += 1;
        } else if norm > r + tol {
            assert!(!is_in, "{p:?} at {norm} should be outside");
        }
        assert!((d - (norm - r).abs()).abs() <= tol, "{p:?}: distance {d}");
        let cn = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        assert!(
            (cn - r).abs() <= tol,
            "closest point {c:?} is off the sphere"
        );
        let dc = ((c[0] - p[0]).powi(2) + (c[1] - p[1]).powi(2) + (c[2] - p[2]).powi(2)).sqrt();
        assert!((dc - d).abs() < 1e-12);
    }
    assert!(checked_inside > 50);
}

#[test]
fn sphere_rays_from_outside_hit_the_near_side() {
    let r = 0.05;
    let q = MeshQuery::new(&sphere(r, 64, 128)).unwrap();
    let origins: Vec<[f64; 3]> = (0..1000)
        .map(|i| {
            let a = i as f64 * 0.0063;
            [0.5 * a.cos(), 0.5 * a.sin(), 0.02 * (i % 7) as f64 - 0.06]
        })
        .collect();
    let dirs: Vec<[f64; 3]> = origins
        .iter()
        .map(|o| unit([-o[0], -o[1], -o[2]]))
        .collect();
    let hits = q.first_hits(&origins, &dirs).unwrap();
    let tol = r * (1.0 - (std::f64::consts::PI / 64.0).cos()) + 1e-5;
    for (o, h) in origins.iter().zip(hits) {
        let dist = (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt();
        let h = h.expect("a ray through the centre hits");
        assert!((h - (dist - r)).abs() <= tol, "{h} vs {}", dist - r);
    }
}

#[test]
fn closest_point_on_triangle_covers_every_voronoi_region() {
    let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let cases = [
        ([0.2, 0.2, 1.0], [0.2, 0.2, 0.0]),   // face
        ([-1.0, -1.0, 0.0], [0.0, 0.0, 0.0]), // vertex a
        ([2.0, -0.5, 0.0], [1.0, 0.0, 0.0]),  // vertex b
        ([-0.5, 2.0, 0.0], [0.0, 1.0, 0.0]),  // vertex c
        ([0.5, -1.0, 0.3], [0.5, 0.0, 0.0]),  // edge ab
        ([-1.0, 0.5, 0.0], [0.0, 0.5, 0.0]),  // edge ac
        ([1.0, 1.0, 0.0], [0.5, 0.5, 0.0]),   // edge bc
    ];
    for (p, want) in cases {
        let got = closest_on_triangle(p, &t);
        for k in 0..3 {
            assert!(
                (got[k] - want[k]).abs() < 1e-12,
                "{p:?}: {got:?} vs {want:?}"
            );
        }
    }
}

#[test]
fn tree_agrees_with_brute_force() {
    let mesh = sphere(0.03, 12, 17);
    let tree = TriangleTree::new(&mesh);
    for i in 0..300 {
        let t = i as f64;
        let p = [
            0.05 * (t * 1.3).sin(),
            0.05 * (t * 0.7).cos(),
            0.05 * (t * 2.1).sin(),
        ];
        let brute = mesh
            .faces
            .iter()
            .map(|f| {
                let c = closest_on_triangle(p, &f.map(|i| mesh.vertices[i as usize]));
                ((c[0] - p[0]).powi(2) + (c[1] - p[1]).powi(2) + (c[2] - p[2]).powi(2)).sqrt()
            })
            .fold(f64::INFINITY, f64::min);
        let (_, d) = tree.closest_point(p).unwrap();
        assert!((d - brute).abs() < 1e-12, "{d} vs {brute}");
    }
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let mut m = cube(0.01);
    m.faces.push([0, 1, 99]);
    assert!(MeshQuery::new(&m).unwrap_err().to_string().contains("99"));
    let q = MeshQuery::new(&cube(0.01)).unwrap();
    assert!(q.first_hits(&[[0.0; 3]], &[]).is_err());
    assert!(q.contains(&[]).unwrap().is_empty());
    assert!(q.first_hits(&[], &[]).unwrap().is_empty());
}
