//! A setting outside its allowed range, named as the config file names it.
//! It imports nothing of the crate, so every config module can use it.

/// A setting outside its allowed range, named as in the config file
/// (`policy.window_s`, `link.watchdog_ms`); a flag that overrides it is
/// checked the same way.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{field} {rule}")]
pub struct InvalidSetting {
    pub field: &'static str,
    /// The rule it breaks, with the value found.
    pub rule: String,
}

/// `Err` naming `field` and its `rule` unless `ok`.
pub fn ensure(
    ok: bool,
    field: &'static str,
    rule: impl FnOnce() -> String,
) -> Result<(), InvalidSetting> {
    match ok {
        true => Ok(()),
        false => Err(InvalidSetting {
            field,
            rule: rule(),
        }),
    }
}
