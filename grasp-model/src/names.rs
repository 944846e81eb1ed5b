//! The spellings of the model's named choices (architecture, EfficientNet-
//! Lite size, head, training mode) as text: [`Display`](std::fmt::Display)
//! writes the one that checkpoints and recipes record (their serde form),
//! [`FromStr`](std::str::FromStr) reads it back. The programs parse their
//! flags with these or with their own clap enums (`grasp-cli`); this crate
//! does not link clap.

use crate::backbone::Architecture;
use crate::checkpoint::TrainMode;
use crate::heads::HeadKind;
use crate::networks::LiteVariant;

/// A name that is none of a choice's spellings.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {what} '{given}' (one of: {})", expected.join(", "))]
pub struct UnknownName {
    /// What was being named ("architecture", "head", ...).
    pub what: &'static str,
    pub given: String,
    /// Every spelling, in declaration order.
    pub expected: Vec<&'static str>,
}

impl UnknownName {
    fn find<T: Copy>(
        what: &'static str,
        given: &str,
        all: impl IntoIterator<Item = T>,
        spell: fn(T) -> &'static str,
    ) -> Result<T, UnknownName> {
        let all: Vec<T> = all.into_iter().collect();
        all.iter()
            .copied()
            .find(|v| spell(*v) == given)
            .ok_or_else(|| UnknownName {
                what,
                given: given.to_string(),
                expected: all.into_iter().map(spell).collect(),
            })
    }
}

macro_rules! spelled {
    ($ty:ty, $what:literal, $all:expr, $spell:expr) => {
        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                let spell: fn($ty) -> &'static str = $spell;
                f.write_str(spell(*self))
            }
        }

        impl std::str::FromStr for $ty {
            type Err = UnknownName;

            fn from_str(s: &str) -> std::result::Result<Self, UnknownName> {
                UnknownName::find($what, s, $all, $spell)
            }
        }
    };
}

spelled!(
    Architecture,
    "architecture",
    Architecture::ALL,
    Architecture::name
);
spelled!(
    LiteVariant,
    "EfficientNet-Lite size",
    LiteVariant::ALL,
    |v| {
        match v {
            LiteVariant::Lite0 => "lite0",
            LiteVariant::Lite1 => "lite1",
            LiteVariant::Lite2 => "lite2",
        }
    }
);
spelled!(HeadKind, "head", HeadKind::ALL, HeadKind::name);
spelled!(TrainMode, "training mode", TrainMode::ALL, TrainMode::name);

#[cfg(test)]
mod tests {
    use super::*;
    use serde::{de::DeserializeOwned, Serialize};
    use std::fmt::Display;
    use std::str::FromStr;

    /// Every variant is written as its serde form and read back from it.
    fn agrees_with_serde<T>(all: &[T], expected: &[&str])
    where
        T: Copy + PartialEq + std::fmt::Debug + Display + FromStr + Serialize + DeserializeOwned,
        <T as FromStr>::Err: std::fmt::Debug,
    {
        let spelled: Vec<String> = all.iter().map(|v| v.to_string()).collect();
        assert_eq!(spelled, expected);
        for v in all {
            let text = v.to_string();
            assert_eq!(serde_json::to_string(v).unwrap(), format!("\"{text}\""));
            assert_eq!(text.parse::<T>().unwrap(), *v);
            let from_serde: T = serde_json::from_str(&format!("\"{text}\"")).unwrap();
            assert_eq!(from_serde, *v);
        }
    }

    #[test]
    fn spellings_are_the_serde_forms() {
        agrees_with_serde(
            &Architecture::ALL,
            &[
                "mobilenet-v2",
                "efficientnet-lite0",
                "efficientnet-lite1",
                "efficientnet-lite2",
            ],
        );
        agrees_with_serde(&LiteVariant::ALL, &["lite0", "lite1", "lite2"]);
        agrees_with_serde(&HeadKind::ALL, &["fc", "lstm", "trace"]);
        agrees_with_serde(
            &TrainMode::ALL,
            &["frozen-pretrained", "from-scratch", "fine-tuned"],
        );
    }

    #[test]
    fn an_unknown_name_lists_the_spellings() {
        let e = "gru".parse::<HeadKind>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "unknown head 'gru' (one of: fc, lstm, trace)"
        );
        assert!("Fc".parse::<HeadKind>().is_err(), "case matters, as before");
    }
}
