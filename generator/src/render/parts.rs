//! The `part` pass: for every pixel, which grasp-part box of the object the
//! visible surface point lies in (0 = none or not the object, k = the k-th
//! part in catalog order), written as an 8-bit `partNNNNN.png` next to the
//! frame.
//!
//! Blender renders only the depth (and, in Cycles, the object index) into a
//! multilayer EXR; the labels are computed here. Each pixel's ray is
//! back-projected to the visible point with the frame's camera pose and
//! intrinsics and carried into the catalog's object frame (undoing the
//! plan's object scale). A pixel is the object's
//! when the object-index pass says so, or (Workbench and EEVEE have no such
//! pass) when the point lies on the object's mesh within a tolerance. It gets
//! the part whose box is nearest, within `tolerance` (inside counts as 0;
//! ties go to the earlier part).

use super::error::{RenderError, Result};
use crate::catalog::TriMesh;
use crate::geometry::TriangleTree;
use crate::plan::validity::Obb;
use crate::plan::wrist::from_wxyz;
use grasp_schema::plan::{CameraIntrinsics, Pose};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Object index of the target object in the instance pass (`render.py`).
const INDEX_OBJECT: f32 = 1.0;

/// A grasp part's box in the object frame, as the catalog gives it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartBox {
    pub name: String,
    pub center: [f64; 3],
    pub rotation_wxyz: [f64; 4],
    /// Full edge lengths, metres.
    pub size: [f64; 3],
}

impl PartBox {
    fn obb(&self) -> Result<Obb> {
        let q = self.rotation_wxyz;
        let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        if !(norm.is_finite() && norm > 1e-9 && self.size.iter().all(|s| *s > 0.0)) {
            return Err(RenderError::Labels(format!(
                "part {}: the box (rotation {q:?}, size {:?}) is degenerate",
                self.name, self.size
            )));
        }
        Ok(Obb {
            center: Vector3::from(self.center),
            rotation: from_wxyz(q),
            half: Vector3::from(self.size) / 2.0,
        })
    }
}

/// The depth and object-index channels of one rendered frame.
#[derive(Debug, Clone)]
pub struct FrameBuffers {
    pub width: usize,
    pub height: usize,
    /// Distance along the camera's view axis (Blender's Z pass), row-major
    /// from the top row.
    pub depth: Vec<f32>,
    /// Object index per pixel (Cycles only).
    pub index: Option<Vec<f32>>,
}

/// Reads Blender's multilayer EXR (`ViewLayer.Depth.Z`, optionally
/// `ViewLayer.Object Index.X`).
pub fn read_exr(path: &Path) -> Result<FrameBuffers> {
    let image =
        exr::prelude::read_all_flat_layers_from_file(path).map_err(|source| RenderError::Exr {
            path: path.to_path_buf(),
            source,
        })?;
    let mut depth = None;
    let mut index = None;
    let mut size = (0, 0);
    for layer in &image.layer_data {
        size = (layer.size.width(), layer.size.height());
        for ch in &layer.channel_data.list {
            let name = ch.name.to_string();
            let values = || ch.sample_data.values_as_f32().collect::<Vec<f32>>();
            if name.ends_with("Depth.Z") {
                depth = Some(values());
            } else if name.ends_with("Object Index.X") {
                index = Some(values());
            }
        }
    }
    let Some(depth) = depth else {
        return Err(RenderError::BadExr {
            path: path.to_path_buf(),
            reason: "no depth channel (*.Depth.Z)".into(),
        });
    };
    let (width, height) = size;
    if !(depth.len() == width * height && index.as_ref().is_none_or(|i| i.len() == depth.len())) {
        return Err(RenderError::BadExr {
            path: path.to_path_buf(),
            reason: format!("channel sizes do not match the {width}x{height} image"),
        });
    }
    Ok(FrameBuffers {
        width,
        height,
        depth,
        index,
    })
}

/// Labels frames of one object.
pub struct PartLabeler {
    boxes: Vec<Obb>,
    mesh: TriangleTree,
    /// How far outside a box a point may lie and still get its label, metres.
    tolerance: f64,
}

impl PartLabeler {
    pub fn new(parts: &[PartBox], mesh: &TriMesh, tolerance: f64) -> Result<Self> {
        if parts.len() >= 256 {
            return Err(RenderError::Labels(format!(
                "{} parts do not fit an 8-bit label image",
                parts.len()
            )));
        }
        Ok(PartLabeler {
            boxes: parts.iter().map(PartBox::obb).collect::<Result<_>>()?,
            mesh: TriangleTree::new(mesh),
            tolerance,
        })
    }

    /// One label per pixel, row-major from the top row. `object` places the
    /// catalog's object scaled along its frame's axes by `scale`
    /// (`ObjectPlacement::axis_scale`).
    pub fn label(
        &self,
        buffers: &FrameBuffers,
        k: &CameraIntrinsics,
        camera: &Pose,
        object: &Pose,
        scale: [f64; 3],
    ) -> Result<Vec<u8>> {
        if !scale.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(RenderError::Labels(format!(
                "the object scale {scale:?} is not positive on every axis"
            )));
        }
        let scale = Vector3::from(scale);
        if (buffers.width, buffers.height) != (k.width as usize, k.height as usize) {
            return Err(RenderError::Labels(format!(
                "the depth image is {}x{} but the intrinsics say {}x{}",
                buffers.width, buffers.height, k.width, k.height
            )));
        }
        let cam_q = from_wxyz(camera.rotation_wxyz);
        let cam_p = Vector3::from(camera.position);
        let obj_q = from_wxyz(object.rotation_wxyz);
        let obj_p = Vector3::from(object.position);
        let mut out = vec![0u8; buffers.depth.len()];
        for (i, label) in out.iter_mut().enumerate() {
            let d = f64::from(buffers.depth[i]);
            if !(d.is_finite() && d > k.clip_near && d < k.clip_far) {
                continue;
            }
            if let Some(index) = &buffers.index {
                if (index[i] - INDEX_OBJECT).abs() > 0.5 {
                    continue;
                }
            }
            let (u, v) = (
                (i % buffers.width) as f64 + 0.5,
                (i / buffers.width) as f64 + 0.5,
            );
            // Camera frame: looks along -Z, +Y up in the image.
            let ray = Vector3::new((u - k.cx) / k.fx, -(v - k.cy) / k.fy, -1.0);
            let world = cam_p + cam_q * (ray * d);
            let local = obj_q
                .inverse_transform_vector(&(world - obj_p))
                .component_div(&scale);
            if buffers.index.is_none() && !self.on_surface(&local, d, k, &scale) {
                continue;
            }
            *label = self.part_of(&local, &scale);
        }
        Ok(out)
    }

    /// Whether a back-projected point lies on the object's mesh, allowing
    /// the depth buffer's error and a pixel's footprint at that depth
    /// (metres; `local` is in the catalog's frame, `scale` metres per unit
    /// along each of its axes).
    fn on_surface(
        &self,
        local: &Vector3<f64>,
        depth: f64,
        k: &CameraIntrinsics,
        scale: &Vector3<f64>,
    ) -> bool {
        let footprint = depth / k.fx.min(k.fy);
        let allowed = self.tolerance + 2.0 * footprint;
        self.mesh
            .closest_point([local.x, local.y, local.z])
            .is_some_and(|(nearest, _)| {
                (Vector3::from(nearest) - local).component_mul(scale).norm() <= allowed
            })
    }

    /// 1 + index of the nearest box within tolerance, or 0. A point inside
    /// several boxes gets the smallest one (the most specific part); equal
    /// boxes go to the earlier part. The tolerance is in metres.
    /// (Stretched unevenly, a box's distance is taken at its largest
    /// stretch: at most a few per cent of the tolerance too strict.)
    fn part_of(&self, local: &Vector3<f64>, scale: &Vector3<f64>) -> u8 {
        let mut best = (0u8, f64::INFINITY, f64::INFINITY);
        for (i, b) in self.boxes.iter().enumerate() {
            let d = b.distance(local) * scale.max();
            let volume = b.half.x * b.half.y * b.half.z;
            if d <= self.tolerance && (d, volume) < (best.1, best.2) {
                best = ((i + 1) as u8, d, volume);
            }
        }
        best.0
    }
}

/// Writes an 8-bit grayscale label image.
pub fn write_labels(path: &Path, width: u32, height: u32, labels: Vec<u8>) -> Result<()> {
    let img = image::GrayImage::from_raw(width, height, labels).ok_or(RenderError::BufferSize(
        "label buffer does not match the image size",
    ))?;
    grasp_support::atomic::write_atomic_with(path, |tmp| -> Result<()> {
        img.save_with_format(tmp, image::ImageFormat::Png)
            .map_err(|e| RenderError::image(format!("cannot write {}", path.display()), e))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 10 cm cube on z in [0, 0.1], two parts: the top slab and the -X face.
    fn cube() -> (TriMesh, Vec<PartBox>) {
        let mut mesh = crate::catalog::shapes::cuboid([0.1, 0.1, 0.1]);
        for v in &mut mesh.vertices {
            v[2] += 0.05;
        }
        let parts = vec![
            PartBox {
                name: "top".into(),
                center: [0.0, 0.0, 0.1],
                rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
                size: [0.1, 0.1, 0.01],
            },
            PartBox {
                name: "side".into(),
                center: [-0.05, 0.0, 0.05],
                rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
                size: [0.01, 0.1, 0.08],
            },
        ];
        (mesh, parts)
    }

    fn intrinsics(px: u32) -> CameraIntrinsics {
        let f = f64::from(px) / 2.0 / 0.4f64.tan();
        CameraIntrinsics {
            width: px,
            height: px,
            fx: f,
            fy: f,
            cx: f64::from(px) / 2.0,
            cy: f64::from(px) / 2.0,
            fov_x_deg: 45.8,
            fov_y_deg: 45.8,
            clip_near: 0.01,
            clip_far: 20.0,
        }
    }

    /// A camera 0.5 m above the cube looking straight down (image up = +X):
    /// the depth image of the top face, computed in closed form.
    fn top_view(px: u32, object: &Pose) -> (Pose, FrameBuffers) {
        top_view_scaled(px, object, [1.0; 3])
    }

    /// The same with the cube scaled by `scale` about its origin along X, Y,
    /// Z (X and Y alike; the camera stays 0.6 m above the origin).
    fn top_view_scaled(px: u32, object: &Pose, scale: [f64; 3]) -> (Pose, FrameBuffers) {
        let s = std::f64::consts::FRAC_1_SQRT_2;
        // Camera -Z = world -Z, camera +Y = world +X: a rotation about Z by -90 deg.
        let camera = Pose {
            position: [
                object.position[0],
                object.position[1],
                object.position[2] + 0.6,
            ],
            rotation_wxyz: [s, 0.0, 0.0, -s],
        };
        let top = (0.6 - 0.1 * scale[2]) as f32;
        let half = 0.05 * scale[0];
        let depth = vec![top; (px * px) as usize];
        // Pixels outside the top face see the floor, far below.
        let k = intrinsics(px);
        let depth = depth
            .iter()
            .enumerate()
            .map(|(i, _)| {
                let (u, v) = ((i as u32 % px) as f64 + 0.5, (i as u32 / px) as f64 + 0.5);
                let d = f64::from(top);
                let (x, y) = ((u - k.cx) / k.fx * d, (v - k.cy) / k.fy * d);
                if x.abs() < half && y.abs() < half {
                    top
                } else {
                    3.0
                }
            })
            .collect();
        (
            camera,
            FrameBuffers {
                width: px as usize,
                height: px as usize,
                depth,
                index: None,
            },
        )
    }

    #[test]
    fn the_top_face_seen_from_above_is_the_top_part() {
        let (mesh, parts) = cube();
        let labeler = PartLabeler::new(&parts, &mesh, 0.005).unwrap();
        let object = Pose {
            position: [0.2, -0.1, 0.75],
            rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
        };
        let (camera, buffers) = top_view(64, &object);
        let labels = labeler
            .label(&buffers, &intrinsics(64), &camera, &object, [1.0; 3])
            .unwrap();
        let on_face = buffers.depth.iter().filter(|d| **d < 1.0).count();
        let top = labels.iter().filter(|l| **l == 1).count();
        assert!(on_face > 100);
        assert_eq!(top, on_face, "every top-face pixel is part 1");
        assert_eq!(labels.iter().filter(|l| **l == 2).count(), 0);
        // Floor pixels are not the object.
        let floor = labels.iter().zip(&buffers.depth).filter(|(_, d)| **d > 1.0);
        assert!(floor.clone().all(|(l, _)| *l == 0));
    }

    #[test]
    fn a_scaled_object_is_labelled_in_the_catalogs_frame() {
        let (mesh, parts) = cube();
        let labeler = PartLabeler::new(&parts, &mesh, 0.005).unwrap();
        let object = Pose {
            position: [0.2, -0.1, 0.75],
            rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
        };
        // Twice the catalog's size: the top face is 0.2 m up and 0.2 m wide.
        let (camera, buffers) = top_view_scaled(64, &object, [2.0; 3]);
        let k = intrinsics(64);
        let on_face = buffers.depth.iter().filter(|d| **d < 1.0).count();
        assert!(on_face > 100);
        let labels = labeler
            .label(&buffers, &k, &camera, &object, [2.0; 3])
            .unwrap();
        assert_eq!(labels.iter().filter(|l| **l == 1).count(), on_face);
        // Read at the catalog's size, the face floats above the object.
        let labels = labeler
            .label(&buffers, &k, &camera, &object, [1.0; 3])
            .unwrap();
        assert!(labels.iter().all(|l| *l == 0));
        let err = labeler
            .label(&buffers, &k, &camera, &object, [0.0; 3])
            .unwrap_err();
        assert!(err.to_string().contains("scale"), "{err}");
        // Stretched along Z alone (`[randomize.proportions]`): the top face
        // is 0.2 m up and 0.1 m wide, labelled only at that stretch.
        let tall = [1.0, 1.0, 2.0];
        let (camera, buffers) = top_view_scaled(64, &object, tall);
        let on_face = buffers.depth.iter().filter(|d| **d < 1.0).count();
        assert!(on_face > 20);
        let labels = labeler.label(&buffers, &k, &camera, &object, tall).unwrap();
        assert_eq!(labels.iter().filter(|l| **l == 1).count(), on_face);
        let labels = labeler
            .label(&buffers, &k, &camera, &object, [1.0; 3])
            .unwrap();
        assert!(labels.iter().all(|l| *l == 0));
    }

    #[test]
    fn the_instance_pass_overrides_the_surface_test() {
        let (mesh, parts) = cube();
        let labeler = PartLabeler::new(&parts, &mesh, 0.005).unwrap();
        let object = Pose {
            position: [0.0, 0.0, 0.75],
            rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
        };
        let (camera, mut buffers) = top_view(32, &object);
        // Say a hand (index 2) covers the whole image.
        buffers.index = Some(vec![2.0; buffers.depth.len()]);
        let k = intrinsics(32);
        let labels = labeler
            .label(&buffers, &k, &camera, &object, [1.0; 3])
            .unwrap();
        assert!(labels.iter().all(|l| *l == 0));
        buffers.index = Some(vec![1.0; buffers.depth.len()]);
        let labels = labeler
            .label(&buffers, &k, &camera, &object, [1.0; 3])
            .unwrap();
        assert!(labels.contains(&1));
    }

    #[test]
    fn a_yawed_object_is_labelled_in_its_own_frame() {
        let (mesh, parts) = cube();
        let labeler = PartLabeler::new(&parts, &mesh, 0.005).unwrap();
        // Half a turn about Z: the top face stays the top face.
        let object = Pose {
            position: [0.0, 0.0, 0.75],
            rotation_wxyz: [0.0, 0.0, 0.0, 1.0],
        };
        let (camera, buffers) = top_view(32, &object);
        let labels = labeler
            .label(&buffers, &intrinsics(32), &camera, &object, [1.0; 3])
            .unwrap();
        assert!(labels.iter().filter(|l| **l == 1).count() > 20);
        // A wrong size is an error, not a panic.
        let err = labeler
            .label(&buffers, &intrinsics(16), &camera, &object, [1.0; 3])
            .unwrap_err();
        assert!(err.to_string().contains("intrinsics"), "{err}");
    }

    #[test]
    fn nested_boxes_give_the_smaller_part() {
        let (mesh, mut parts) = cube();
        // A big part enclosing the whole cube, listed first.
        parts.insert(
            0,
            PartBox {
                name: "all".into(),
                center: [0.0, 0.0, 0.05],
                rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
                size: [0.2, 0.2, 0.2],
            },
        );
        let labeler = PartLabeler::new(&parts, &mesh, 0.005).unwrap();
        let part_of = |x, y, z| labeler.part_of(&Vector3::new(x, y, z), &Vector3::repeat(1.0));
        assert_eq!(part_of(0.0, 0.0, 0.1), 2, "top");
        assert_eq!(part_of(-0.05, 0.0, 0.05), 3, "side");
        assert_eq!(part_of(0.05, 0.0, 0.02), 1, "all");
        assert_eq!(part_of(0.5, 0.0, 0.0), 0, "none");
    }

    #[test]
    fn degenerate_boxes_are_refused_by_name() {
        let (mesh, mut parts) = cube();
        parts[1].size = [0.0, 0.1, 0.1];
        let err = PartLabeler::new(&parts, &mesh, 0.005).err().unwrap();
        assert!(err.to_string().contains("part side"), "{err}");
    }
}
