//! Where plans come from: every sequence's key in canonical order, and its
//! plan. The dataset (layout, verification) needs only this; the renderer
//! needs more of a source (`render::source::RenderSource`). The real source
//! is the built-in catalog and the planner: the planner holds Python-backed
//! ray casters that must stay on one thread, so it runs on its own thread
//! and answers plan requests over a channel.

use super::error::{PlanError, Result};
use super::{sequence_keys, Planner};
use crate::catalog::Catalog;
use crate::config::GeneratorConfig;
use grasp_schema::plan::substream_seed;
use grasp_schema::taxonomy::Preshape;
use grasp_schema::{SequenceKey, SequencePlan};
use std::sync::mpsc::{channel, Sender};
use std::sync::Mutex;

/// A key with what the dataset layout needs before planning.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedKey {
    pub key: SequenceKey,
    pub category: String,
    pub preshape: Preshape,
}

pub trait PlanSource: Send + Sync {
    /// Every sequence of the dataset, in canonical order. Folder numbers and
    /// shards derive from positions in this list, so it must not depend on
    /// the shard or on what is already rendered.
    fn keys(&self) -> Result<Vec<PlannedKey>>;
    fn plan(&self, key: &SequenceKey) -> Result<SequencePlan>;
}

type PlanReply = Sender<Result<SequencePlan>>;

/// The catalog-and-planner source of a generator config.
pub struct PlannerSource {
    pub(crate) config: GeneratorConfig,
    pub(crate) catalog: Catalog,
    requests: Mutex<Sender<(SequenceKey, PlanReply)>>,
}

impl PlannerSource {
    pub fn new(config: &GeneratorConfig) -> Result<Self> {
        let catalog = Catalog::builtin().map_err(|e| PlanError::BuiltinCatalog(Box::new(e)))?;
        super::check::check(config, &catalog)?;
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
            .map_err(|_| PlanError::PlannerStopped)?
            .map_err(|e| PlanError::Setup(Box::new(e)))?;
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
                let spec =
                    self.catalog
                        .object(&key.object)
                        .ok_or_else(|| PlanError::UnknownObject {
                            object: key.object.clone(),
                            known: None,
                        })?;
                let part = spec
                    .parts
                    .iter()
                    .find(|p| p.name == key.part)
                    .ok_or_else(|| PlanError::UnknownPart {
                        object: key.object.clone(),
                        part: key.part.clone(),
                        quoted: true,
                        parts: None,
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
            .map_err(|_| PlanError::PlannerStopped)?;
        let mut plan = rx.recv().map_err(|_| PlanError::PlannerStopped)??;
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
}
