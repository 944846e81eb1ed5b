//! The decision policy's flags (`grasp-policy`), which `hannes-run` and
//! `grasp-train eval` take the same way: the hand and its evaluation decide
//! by one policy.

use clap::{Args, ValueEnum};
use grasp_policy::{OnInvalid, PolicyConfig};
use grasp_schema::taxonomy::{Preshape, UnknownName};

/// What an invalid model output does ([`OnInvalid`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OnInvalidArg {
    /// End the approach without commanding the hand.
    Abort,
    /// Leave the frame out of the vote and go on.
    Skip,
}

impl From<OnInvalidArg> for OnInvalid {
    fn from(a: OnInvalidArg) -> OnInvalid {
        match a {
            OnInvalidArg::Abort => OnInvalid::Abort,
            OnInvalidArg::Skip => OnInvalid::Skip,
        }
    }
}

/// The policy's settings as flags; each given flag replaces the value of
/// the config (a file's, or the defaults).
#[derive(Args, Clone, Debug, Default)]
pub struct DecisionArgs {
    /// Approach window in seconds after the trigger (default 2).
    #[arg(long, value_name = "SECONDS")]
    pub window: Option<f64>,
    /// Decide early once the leading pre-shape is this many votes ahead.
    #[arg(long, value_name = "VOTES")]
    pub early_margin: Option<u32>,
    /// Pre-shape sent on low confidence (power, lateral, pinch, pinch3), or
    /// `none` to send nothing.
    #[arg(long, value_name = "PRESHAPE")]
    pub fallback: Option<String>,
    /// Fewer pre-shape votes than this is a weak vote (default 3).
    #[arg(long, value_name = "VOTES")]
    pub min_votes: Option<u32>,
    /// Minimum share of the pre-shape votes the winner must get (default
    /// 0.5).
    #[arg(long, value_name = "SHARE")]
    pub min_share: Option<f64>,
    /// Minimum mean probability of the winning class (default 0.5).
    #[arg(long, value_name = "P")]
    pub min_confidence: Option<f64>,
    /// What an invalid model output (NaN, Inf) does.
    #[arg(long, value_enum)]
    pub on_invalid: Option<OnInvalidArg>,
}

impl DecisionArgs {
    /// Lays the given flags over `policy` (validate it afterwards).
    pub fn apply(&self, policy: &mut PolicyConfig) -> Result<(), UnknownName> {
        if let Some(w) = self.window {
            policy.window_s = w;
        }
        if self.early_margin.is_some() {
            policy.early_margin = self.early_margin;
        }
        if let Some(f) = &self.fallback {
            policy.fallback = match f.as_str() {
                "none" => None,
                name => Some(name.parse::<Preshape>()?),
            };
        }
        if let Some(v) = self.min_votes {
            policy.min_votes = v;
        }
        if let Some(v) = self.min_share {
            policy.min_share = v;
        }
        if let Some(c) = self.min_confidence {
            policy.min_confidence = c;
        }
        if let Some(o) = self.on_invalid {
            policy.on_invalid = o.into();
        }
        Ok(())
    }
}
