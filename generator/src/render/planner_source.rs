//! The catalog-and-planner source ([`crate::plan::PlannerSource`]) as a
//! render source: meshes, part boxes and the scene from the catalog and the
//! config.

use super::error::{RenderError, Result};
use super::parts::PartBox;
use super::scene::{Room, Table};
use super::source::{Mesh, RenderSource};
use super::SceneGeometry;
use crate::config::GeneratorConfig;
use crate::plan::PlannerSource;
use std::sync::Arc;

/// The catalog-and-planner source of a generator config.
pub fn from_config(config: &GeneratorConfig) -> Result<Arc<dyn RenderSource>> {
    Ok(Arc::new(PlannerSource::new(config)?))
}

impl RenderSource for PlannerSource {
    fn mesh(&self, object: &str) -> Result<Mesh> {
        let spec = self
            .catalog
            .object(object)
            .ok_or_else(|| RenderError::UnknownObject {
                object: object.to_string(),
            })?;
        let m = spec.mesh()?;
        Ok(Mesh {
            vertices: m.vertices,
            faces: m.faces,
        })
    }

    fn scene(&self) -> SceneGeometry {
        scene_from_config(&self.config.plan.scene)
    }

    fn object_color_range(&self, object: &str) -> Option<crate::catalog::ColorRange> {
        self.catalog.object(object).and_then(|spec| spec.color)
    }

    fn parts(&self, object: &str) -> Result<Vec<PartBox>> {
        let spec = self
            .catalog
            .object(object)
            .ok_or_else(|| RenderError::UnknownObject {
                object: object.to_string(),
            })?;
        Ok(spec
            .parts
            .iter()
            .map(|p| PartBox {
                name: p.name.clone(),
                center: p.center,
                rotation_wxyz: p.rotation_wxyz,
                size: p.size,
            })
            .collect())
    }
}

/// The planner's room and table, in the form the Blender scene is built from.
pub fn scene_from_config(s: &crate::plan::SceneConfig) -> SceneGeometry {
    let [rx, ry, rh] = s.room_size;
    let [tx, ty] = s.table_center;
    let [sx, sy] = s.table_size;
    SceneGeometry {
        room: Room {
            min_xy: [-rx / 2.0, -ry / 2.0],
            max_xy: [rx / 2.0, ry / 2.0],
            height: rh,
        },
        table: Table {
            min_xy: [tx - sx / 2.0, ty - sy / 2.0],
            max_xy: [tx + sx / 2.0, ty + sy / 2.0],
            height: s.table_height,
            thickness: s.table_thickness,
        },
    }
}
