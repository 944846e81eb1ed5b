//! Closest-point queries on a triangle mesh through a bounding-volume
//! hierarchy. trimesh's own `closest_point` walks an rtree from Python, one
//! point at a time, and takes seconds for a few thousand points far from the
//! surface; this tree answers the same query in microseconds.

use crate::catalog::TriMesh;

type V3 = [f64; 3];

const LEAF_SIZE: usize = 4;

#[derive(Debug, Clone)]
struct Node {
    min: V3,
    max: V3,
    /// Leaf: triangles `start..start + count`; inner: children `start` and `start + 1`.
    start: usize,
    count: usize,
}

/// A BVH over a mesh's triangles.
#[derive(Debug, Clone)]
pub struct TriangleTree {
    triangles: Vec<[V3; 3]>,
    nodes: Vec<Node>,
}

impl TriangleTree {
    pub fn new(mesh: &TriMesh) -> TriangleTree {
        let mut triangles: Vec<[V3; 3]> = mesh
            .faces
            .iter()
            .map(|f| f.map(|i| mesh.vertices[i as usize]))
            .collect();
        let mut nodes = Vec::with_capacity(2 * triangles.len() / LEAF_SIZE + 1);
        if !triangles.is_empty() {
            nodes.push(Node {
                min: [0.0; 3],
                max: [0.0; 3],
                start: 0,
                count: triangles.len(),
            });
            build(&mut triangles, 0, &mut nodes);
        }
        TriangleTree { triangles, nodes }
    }

    /// The closest point on the mesh surface to `p` and its distance, or
    /// `None` for an empty mesh.
    pub fn closest_point(&self, p: V3) -> Option<(V3, f64)> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best = (p, f64::INFINITY); // (point, squared distance)
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i];
            if box_dist2(p, node.min, node.max) >= best.1 {
                continue;
            }
            if node.count > 0 {
                for tri in &self.triangles[node.start..node.start + node.count] {
                    let q = closest_on_triangle(p, tri);
                    let d2 = dist2(p, q);
                    if d2 < best.1 {
                        best = (q, d2);
                    }
                }
            } else {
                // Visit the nearer child first so the far one is usually pruned.
                let (a, b) = (node.start, node.start + 1);
                let da = box_dist2(p, self.nodes[a].min, self.nodes[a].max);
                let db = box_dist2(p, self.nodes[b].min, self.nodes[b].max);
                if da < db {
                    stack.extend([b, a]);
                } else {
                    stack.extend([a, b]);
                }
            }
        }
        Some((best.0, best.1.sqrt()))
    }
}

/// Splits node `index` (whose triangle range is set) until its leaves hold at
/// most `LEAF_SIZE` triangles. Siblings are stored next to each other.
fn build(tris: &mut [[V3; 3]], index: usize, nodes: &mut Vec<Node>) {
    let (start, end) = (nodes[index].start, nodes[index].start + nodes[index].count);
    let (min, max) = bounds(tris[start..end].iter().flatten());
    nodes[index].min = min;
    nodes[index].max = max;
    if end - start <= LEAF_SIZE {
        return;
    }
    let centroids = tris[start..end].iter().map(centroid).collect::<Vec<_>>();
    let (cmin, cmax) = bounds(centroids.iter());
    let axis = (0..3)
        .max_by(|&a, &b| (cmax[a] - cmin[a]).total_cmp(&(cmax[b] - cmin[b])))
        .unwrap_or(0);
    let mid = start + (end - start) / 2;
    tris[start..end].select_nth_unstable_by(mid - start, |a, b| {
        centroid(a)[axis].total_cmp(&centroid(b)[axis])
    });
    let left = nodes.len();
    for (s, e) in [(start, mid), (mid, end)] {
        nodes.push(Node {
            min,
            max,
            start: s,
            count: e - s,
        });
    }
    nodes[index].start = left;
    nodes[index].count = 0;
    build(tris, left, nodes);
    build(tris, left + 1, nodes);
}

fn centroid(t: &[V3; 3]) -> V3 {
    [0, 1, 2].map(|k| (t[0][k] + t[1][k] + t[2][k]) / 3.0)
}

fn bounds<'a>(points: impl Iterator<Item = &'a V3>) -> (V3, V3) {
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
    }
    (min, max)
}

fn box_dist2(p: V3, min: V3, max: V3) -> f64 {
    (0..3)
        .map(|k| {
            let d = (min[k] - p[k]).max(0.0).max(p[k] - max[k]);
            d * d
        })
        .sum()
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn dist2(a: V3, b: V3) -> f64 {
    let d = sub(a, b);
    dot(d, d)
}

fn lerp(a: V3, ab: V3, t: f64) -> V3 {
    [a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]]
}

/// Closest point on triangle `t` to `p`, by the Voronoi regions of its
/// vertices, edges and face (Ericson, Real-Time Collision Detection, 5.1.5).
pub fn closest_on_triangle(p: V3, t: &[V3; 3]) -> V3 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return lerp(a, ab, d1 / (d1 - d3));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return lerp(a, ac, d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return lerp(b, sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        // Degenerate (zero-area) triangle: fall back to its nearest vertex.
        return *[a, b, c]
            .iter()
            .min_by(|x, y| dist2(p, **x).total_cmp(&dist2(p, **y)))
            .unwrap_or(&a);
    }
    let (v, w) = (vb / denom, vc / denom);
    [
        a[0] + ab[0] * v + ac[0] * w,
        a[1] + ab[1] * v + ac[1] * w,
        a[2] + ab[2] * v + ac[2] * w,
    ]
}
