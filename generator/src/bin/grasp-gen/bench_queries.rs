//! `grasp-gen objects bench-queries`, a benchmark of the binary (not the
//! library): timings of the mesh queries the
//! planner and the validation use, per object and ray backend.

use crate::objects::{load_unchecked, CatalogArg};
use anyhow::Result;
use clap::Args;
use generator::catalog::Catalog;
use generator::geometry::{MeshQuery, RayBackend};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

/// `objects bench-queries`: the catalog and the workload size.
#[derive(Args, Debug)]
pub struct BenchArgs {
    #[command(flatten)]
    pub catalog: CatalogArg,
    /// Rays (and inside-test points) per object.
    #[arg(long, default_value_t = 20_000)]
    pub rays: usize,
    /// Closest-point queries per object (trimesh's version is slow).
    #[arg(long, default_value_t = 200)]
    pub points: usize,
}

/// Runs `objects bench-queries`.
pub fn run_args(a: &BenchArgs) -> Result<()> {
    run(&load_unchecked(&a.catalog)?, a.rays, a.points)
}

type Points = Vec<[f64; 3]>;

/// Rays from points 0.3-0.6 m away towards points in the bounding box (like
/// a wrist camera looking at the object), and points in the box grown by 20 %.
fn workload(lo: [f64; 3], hi: [f64; 3], n: usize, seed: u64) -> (Points, Points, Points) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let in_box = |rng: &mut ChaCha8Rng, grow: f64| -> [f64; 3] {
        std::array::from_fn(|k| {
            let (c, h) = ((lo[k] + hi[k]) / 2.0, (hi[k] - lo[k]) / 2.0 * grow);
            c + rng.gen_range(-1.0..=1.0) * h
        })
    };
    let (mut origins, mut dirs, mut points) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..n {
        let target = in_box(&mut rng, 1.0);
        let d: [f64; 3] = std::array::from_fn(|_| rng.gen_range(-1.0..1.0));
        let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-9);
        let dist = rng.gen_range(0.3..0.6);
        let o = std::array::from_fn(|k| target[k] + d[k] / norm * dist);
        origins.push(o);
        dirs.push(std::array::from_fn(|k| -d[k] / norm));
        points.push(in_box(&mut rng, 1.2));
    }
    (origins, dirs, points)
}

pub fn run(catalog: &Catalog, rays: usize, n_closest: usize) -> Result<()> {
    println!(
        "{:<20} {:>6} {:>12} {:>12} {:>12} {:>12} {:>12} {:>12}",
        "object",
        "faces",
        "embree Mray/s",
        "rtree Mray/s",
        "embree Mpt/s",
        "rtree Mpt/s",
        "bvh cp/s",
        "trimesh cp/s"
    );
    let mut totals = [0.0f64; 6];
    for (i, o) in catalog.objects.iter().enumerate() {
        let mesh = o.mesh()?;
        let (lo, hi) = mesh.bounds();
        let (origins, dirs, points) = workload(lo, hi, rays, i as u64);
        let closest = &points[..n_closest.min(points.len())];
        let mut row = [0.0f64; 6];
        for (b, backend) in [RayBackend::Auto, RayBackend::Triangle]
            .into_iter()
            .enumerate()
        {
            let q = MeshQuery::with_backend(&mesh, backend)?;
            let t = Instant::now();
            q.first_hits(&origins, &dirs)?;
            row[b] = t.elapsed().as_secs_f64();
            let t = Instant::now();
            q.contains(&points)?;
            row[2 + b] = t.elapsed().as_secs_f64();
            if b == 0 {
                let t = Instant::now();
                q.closest_points(closest)?;
                row[4] = t.elapsed().as_secs_f64();
                let t = Instant::now();
                q.trimesh_closest_distances(closest)?;
                row[5] = t.elapsed().as_secs_f64();
            }
        }
        let rate = |n: usize, s: f64| n as f64 / s.max(1e-12);
        println!(
            "{:<20} {:>6} {:>12.2} {:>12.3} {:>12.2} {:>12.3} {:>12.0} {:>12.0}",
            o.id,
            mesh.faces.len(),
            rate(rays, row[0]) / 1e6,
            rate(rays, row[1]) / 1e6,
            rate(rays, row[2]) / 1e6,
            rate(rays, row[3]) / 1e6,
            rate(closest.len(), row[4]),
            rate(closest.len(), row[5]),
        );
        for k in 0..6 {
            totals[k] += row[k];
        }
    }
    let n = catalog.objects.len();
    println!(
        "all: rays embree {:.2} s, rtree {:.2} s (x{:.1}); inside embree {:.2} s, rtree {:.2} s (x{:.1}); \
         closest points bvh {:.4} s, trimesh {:.2} s (x{:.0}); {} objects x {rays} rays, {} closest points each",
        totals[0],
        totals[1],
        totals[1] / totals[0].max(1e-12),
        totals[2],
        totals[3],
        totals[3] / totals[2].max(1e-12),
        totals[4],
        totals[5],
        totals[5] / totals[4].max(1e-12),
        n,
        n_closest
    );
    Ok(())
}
