//! What the assets role reports: whether the world's bundle was found in the asset cache or
//! built into it. `sim-worker assets` prints it as one JSON line and writes it to its
//! `--report-file` (the `<run>-assets` Job's termination message, which the operator reads
//! into the `AssetsReady` condition); `sadesim run` and `sadesim assets build` print its
//! text form.

use serde::{Deserialize, Serialize};

/// Whether the world's bundle came from the cache or was built.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "outcome", rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum AssetsOutcome {
    /// The cache already held a complete, verified entry for the key.
    CacheHit { url: String },
    /// The assets were built and stored; `replaced` says what was wrong with an entry that
    /// was there (partial, damaged) and is now rebuilt.
    Built {
        url: String,
        buildings: usize,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        replaced: Option<String>,
    },
}

impl AssetsOutcome {
    /// The entry's URL (`<cache>/assets/<key>/world/`).
    pub fn url(&self) -> &str {
        match self {
            AssetsOutcome::CacheHit { url } | AssetsOutcome::Built { url, .. } => url,
        }
    }

    /// The `AssetsReady` condition's reason: `CacheHit` or `Built`.
    pub fn reason(&self) -> &'static str {
        match self {
            AssetsOutcome::CacheHit { .. } => "CacheHit",
            AssetsOutcome::Built { .. } => "Built",
        }
    }
}

impl std::fmt::Display for AssetsOutcome {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AssetsOutcome::CacheHit { url } => write!(f, "asset cache hit: {url}"),
            AssetsOutcome::Built { url, buildings, replaced: None } => {
                write!(f, "assets built: {buildings} buildings -> {url}")
            }
            AssetsOutcome::Built { url, buildings, replaced: Some(why) } => {
                write!(f, "assets rebuilt ({why}): {buildings} buildings -> {url}")
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_json_line_names_the_outcome_and_round_trips() {
        let hit = AssetsOutcome::CacheHit { url: "s3://b/assets/k/world/".into() };
        assert_eq!(serde_json::to_string(&hit).unwrap(), r#"{"outcome":"cacheHit","url":"s3://b/assets/k/world/"}"#);
        let built = AssetsOutcome::Built { url: "u".into(), buildings: 3, replaced: Some("world.bin: damaged".into()) };
        let line = serde_json::to_string(&built).unwrap();
        assert_eq!(line, r#"{"outcome":"built","url":"u","buildings":3,"replaced":"world.bin: damaged"}"#);
        assert_eq!(serde_json::from_str::<AssetsOutcome>(&line).unwrap(), built);
        assert_eq!((hit.reason(), built.reason()), ("CacheHit", "Built"));
    }
}
