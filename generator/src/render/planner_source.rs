//! The real plan source: the built-in catalog and the planner. The planner
//! holds Python-backed ray casters that must stay on one thread, so it runs
//! on its own thread and answers plan requests over a channel.

use super::parts::PartBox;
use super::scene::{Room, Table};
use super::source::{Mesh, PlanSource, PlannedKey};
use super::SceneGeometry;
use crate::catalog::Catalog;
use crate::config::GeneratorConfig;
use crate::plan::{sequence_keys, Planner};
use anyhow::{anyhow, Context, Result};
use grasp_schema::plan::substream_seed;
use grasp_schema::{SequenceKey, SequencePlan};
use std::sync::mpsc::{channel, Sender};
use std::sync::{Arc, Mutex};

type PlanReply = Sender<Result<SequencePlan>>;

pub struct PlannerSource {
    config: GeneratorConfig,
    catalog: Catalog,
    requests: Mutex<Sender<(SequenceKey, PlanReply)>>,
}

/// The catalog-and-planner source of a generator config.
pub fn from_config(config: &GeneratorConfig) -> Result<Arc<dyn PlanSource>> {
    Ok(Arc::new(PlannerSource::new(config)?))
}

impl PlannerSource {
    pub fn new(config: &GeneratorConfig) -> Result<Self> {
        let catalog = Catalog::builtin().context("loading the built-in catalog")?;
        config.check(&catalog)?;
        let (tx, rx) = channel::<(SequenceKey, PlanReply)>();
        let (ready_tx, ready_rx) = channel::<Result<()>>();
        let (cfg, cat) = (config.clone(), catalog.clone());
        std::thread::spawn(move || {
            let planner = match Planner::new(&cfg, &cat) {
                Ok(p) => {
                    let _ = ready_tx.send(Ok(()));
                    p
                }
                Err(e) => {
                    let _ = ready_tx.send(Err(e));
                    return;
                }
            };
            for (key, reply) in rx {
                let _ = reply.send(planner.plan(&key));
            }
        });
        ready_rx
            .recv()
            .map_err(|_| anyhow!("the planner thread stopped"))?
            .context("setting up the planner")?;
        Ok(PlannerSource {
            config: config.clone(),
            catalog,
            requests: Mutex::new(tx),
        })
    }
}

impl PlanSource for PlannerSource {
    fn keys(&self) -> Result<Vec<PlannedKey>> {
        sequence_keys(&self.config, &self.catalog)
            .into_iter()
            .map(|key| {
                let spec = self
                    .catalog
                    .object(&key.object)
                    .with_context(|| format!("unknown object '{}'", key.object))?;
                let part = spec
                    .parts
                    .iter()
                    .find(|p| p.name == key.part)
                    .with_context(|| {
                        format!("object '{}' has no part '{}'", key.object, key.part)
                    })?;
                Ok(PlannedKey {
                    category: spec.category.clone(),
                    preshape: part.grasp_type.preshape(),
                    key,
                })
            })
            .collect()
    }

    fn plan(&self, key: &SequenceKey) -> Result<SequencePlan> {
        let (tx, rx) = channel();
        self.requests
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .send((key.clone(), tx))
            .map_err(|_| anyhow!("the planner thread stopped"))?;
        let mut plan = rx
            .recv()
            .map_err(|_| anyhow!("the planner thread stopped"))??;
        if plan.appearance.is_none() {
            let seed = substream_seed(plan.stream_seed, "appearance");
            plan.appearance = Some(crate::appearance::sample(
                &self.config.appearance,
                key.condition,
                seed,
            ));
        }
        Ok(plan)
    }

    fn mesh(&self, object: &str) -> Result<Mesh> {
        let spec = self
            .catalog
            .object(object)
            .with_context(|| format!("unknown object '{object}'"))?;
        let m = spec.mesh()?;
        Ok(Mesh {
            vertices: m.vertices,
            faces: m.faces,
        })
    }

    fn scene(&self) -> SceneGeometry {
        scene_from_config(&self.config.plan.scene)
    }

    fn parts(&self, object: &str) -> Result<Vec<PartBox>> {
        let spec = self
            .catalog
            .object(object)
            .with_context(|| format!("unknown object '{object}'"))?;
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
