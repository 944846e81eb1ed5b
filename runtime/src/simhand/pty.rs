//! A simulated hand on a pseudo-terminal, reached through a link (a
//! symlink, the way udev's `/dev/serial/by-id` links name a real adapter)
//! whose owner is recorded beside it (`crate::ptylink`). Unplugging closes
//! the pseudo-terminal and removes the link; plugging in makes a new one.

use super::faults::FaultSpec;
use super::server::{Plug, RunningHand};
use super::HandEvent;
use crate::ptylink::{PtyError, PtyLink};
use crate::transport::Duplex;
use std::io;
use std::path::{Path, PathBuf};

/// Why a simulated hand on a pseudo-terminal did not start.
#[derive(Debug, thiserror::Error)]
pub enum PtyHandError {
    #[error(transparent)]
    Pty(#[from] PtyError),
    #[error("cannot start the simulated hand")]
    Start(#[source] io::Error),
}

/// Makes a fresh pseudo-terminal, linked at a fixed path, on every plug.
pub struct PtyPlug {
    link: PathBuf,
    current: Option<PtyLink>,
    /// The first pseudo-terminal, made by [`PtyPlug::new`] so that errors
    /// (a missing folder) show at once.
    ready: Option<serialport::TTYPort>,
}

impl PtyPlug {
    pub fn new(link: &Path) -> Result<PtyPlug, PtyError> {
        let (master, current) = PtyLink::create(link)?;
        Ok(PtyPlug {
            link: link.to_path_buf(),
            current: Some(current),
            ready: Some(master),
        })
    }
}

impl Plug for PtyPlug {
    fn plug(&mut self) -> io::Result<Box<dyn Duplex>> {
        if let Some(master) = self.ready.take() {
            return Ok(Box::new(master));
        }
        let (master, current) = PtyLink::create(&self.link).map_err(io::Error::other)?;
        self.current = Some(current);
        Ok(Box::new(master))
    }

    fn unplug(&mut self) {
        self.ready = None;
        self.current = None; // removes the link and closes the slave side
    }

    fn describe(&self) -> String {
        match &self.current {
            Some(c) => format!("{} -> {}", self.link.display(), c.target().display()),
            None => self.link.display().to_string(),
        }
    }
}

/// A simulated hand on a fresh pseudo-terminal pair. The host opens
/// [`PtyHand::path`]. Dropping it "unplugs" the device: the slave side hangs
/// up and the link disappears.
pub struct PtyHand {
    pub hand: RunningHand,
    path: PathBuf,
}

impl PtyHand {
    pub fn plug(
        link_path: &Path,
        sink: impl FnMut(&HandEvent) + Send + 'static,
    ) -> Result<PtyHand, PtyHandError> {
        Self::plug_with_faults(link_path, FaultSpec::default(), sink)
    }

    /// As [`PtyHand::plug`], injecting `faults` on the link.
    pub fn plug_with_faults(
        link_path: &Path,
        faults: FaultSpec,
        sink: impl FnMut(&HandEvent) + Send + 'static,
    ) -> Result<PtyHand, PtyHandError> {
        let plug = PtyPlug::new(link_path)?;
        let hand = RunningHand::start(Box::new(plug), faults, sink).map_err(PtyHandError::Start)?;
        Ok(PtyHand {
            hand,
            path: link_path.to_path_buf(),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}
