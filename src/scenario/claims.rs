//! Paper claims a scenario reproduces: what the paper says, its figure, and how to measure
//! ours from the runs (`claims` in a scenario file). `report::claims` evaluates them.
//!
//! ```json
//! "claims": [{
//!   "paper": "004 §4, Table 2",
//!   "claim": "street scene: 27 fps on 24 cores",
//!   "paper_value": "27 fps",
//!   "measure": {
//!     "figure": "per_second.model_ms",
//!     "where": { "algorithm": "soft_izb", "backend": "cpu-model" }
//!   },
//!   "expect": "> 10"
//! }]
//! ```

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_with::skip_serializing_none;

use crate::error::InputError;

/// A paper's claim and the measurement of ours that it is compared with.
#[skip_serializing_none]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Claim {
    /// The paper and where it says it, e.g. `"004 §4, Table 2"`.
    pub paper: String,
    /// What the paper says, in words.
    pub claim: String,
    /// The paper's figure as it prints it, when it gives one.
    pub paper_value: Option<String>,
    pub measure: Measure,
    /// A condition our figure must meet for the claim to hold (`"< 1"`, `">= 0.9"`); every
    /// value must meet it when the measure lists several.
    pub expect: Option<String>,
}

/// Which runs to take and which of their figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Measure {
    /// A figure of a run:
    /// - a dotted path into its record (`model_ms`, `error.mae_shadow`, `counters.fill`,
    ///   `params.light_size`);
    /// - `counters.A+B+...`: the sum of several counters (`counters.mem_est.depth.read_bytes+
    ///   mem_est.stencil.read_bytes`), absent unless the run records every one;
    /// - `per_second.PATH`: 1000 / the figure at PATH (frames per second from a time in ms);
    /// - `phase_share.PHASE.TIME`: the phase's `TIME` (`model_ms`, `gpu_ms`, `wall_ms`) over
    ///   the sum of all phases' `TIME`; `PHASE` may join several with `+`
    ///   (`silhouettes+volumes`: their times together).
    pub figure: String,
    /// Runs whose fields equal these values: `scenario` (default: the scenario stating the
    /// claim), `algorithm`, `backend`, `scene`, `light`, or a parameter (`triangles`, `light_size`, `map_resolution`, `tile_size`,
    /// `image`, `occluder_height`, `occluder_offset`, `cores`).
    #[serde(default, rename = "where")]
    pub select: BTreeMap<String, serde_json::Value>,
    /// How the values of the matching runs become the figure compared with the claim.
    #[serde(default)]
    pub aggregate: Aggregate,
    /// Divides by this measure (both reduced to one value), for ratios such as "error of A
    /// over error of B".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub over: Option<Box<Measure>>,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Aggregate {
    /// Every matching run's value, labelled by its case.
    #[default]
    Each,
    Mean,
    Min,
    Max,
    Sum,
}

/// Fields a `where` may name.
pub const SELECT_KEYS: [&str; 13] = [
    "scenario",
    "algorithm",
    "backend",
    "scene",
    "light",
    "triangles",
    "light_size",
    "map_resolution",
    "tile_size",
    "image",
    "occluder_height",
    "occluder_offset",
    "cores",
];

/// A parsed `expect`: comparison and bound.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Expect {
    pub op: &'static str,
    pub bound: f64,
}

impl Expect {
    const OPS: [&'static str; 4] = ["<=", ">=", "<", ">"];

    pub fn parse(s: &str) -> Result<Expect, String> {
        let t = s.trim();
        let op = Self::OPS
            .into_iter()
            .find(|op| t.starts_with(op))
            .ok_or_else(|| format!("'{s}' must start with one of <, <=, >, >="))?;
        let bound: f64 = t[op.len()..]
            .trim()
            .parse()
            .ok()
            .filter(|b: &f64| b.is_finite())
            .ok_or_else(|| format!("'{s}' must end with a finite number"))?;
        Ok(Expect { op, bound })
    }

    pub fn holds(&self, v: f64) -> bool {
        match self.op {
            "<" => v < self.bound,
            "<=" => v <= self.bound,
            ">" => v > self.bound,
            _ => v >= self.bound,
        }
    }
}

/// Checks the claims of a scenario; errors name the JSON path.
pub fn validate(claims: &[Claim]) -> Result<(), InputError> {
    for (i, c) in claims.iter().enumerate() {
        let at = format!("$.claims[{i}]");
        if c.paper.trim().is_empty() || c.claim.trim().is_empty() {
            return Err(InputError::new(at, "`paper` and `claim` must not be empty"));
        }
        if let Some(e) = &c.expect {
            Expect::parse(e).map_err(|m| InputError::new(format!("{at}.expect"), m))?;
        }
        measure(&format!("{at}.measure"), &c.measure)?;
    }
    Ok(())
}

fn measure(at: &str, m: &Measure) -> Result<(), InputError> {
    let path = m
        .figure
        .strip_prefix("per_second.")
        .unwrap_or(&m.figure)
        .to_string();
    let bad_figure =
        |why: &str| InputError::new(format!("{at}.figure"), format!("'{}' {why}", m.figure));
    if path.is_empty() || path.split('.').any(str::is_empty) {
        return Err(bad_figure("is not a dotted path"));
    }
    if let Some(rest) = m.figure.strip_prefix("phase_share.") {
        match rest.rsplit_once('.') {
            Some((phase, "model_ms" | "gpu_ms" | "wall_ms"))
                if !phase.split('+').any(str::is_empty) => {}
            _ => {
                return Err(bad_figure(
                    "must be phase_share.PHASE[+PHASE...].(model_ms|gpu_ms|wall_ms)",
                ))
            }
        }
    }
    for key in m.select.keys() {
        if !SELECT_KEYS.contains(&key.as_str()) {
            return Err(InputError::new(
                format!("{at}.where.{key}"),
                crate::error::unknown_name("run field", key, &SELECT_KEYS),
            ));
        }
    }
    if let Some(over) = &m.over {
        if m.aggregate == Aggregate::Each || over.aggregate == Aggregate::Each {
            return Err(InputError::new(
                format!("{at}.aggregate"),
                "a ratio (`over`) needs one value on each side: aggregate mean, min, max or sum",
            ));
        }
        measure(&format!("{at}.over"), over)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expectations_parse_and_compare() {
        let e = Expect::parse(" <= 0.5").unwrap();
        assert!(e.holds(0.5) && !e.holds(0.51));
        assert!(Expect::parse(">2").unwrap().holds(3.0));
        assert!(Expect::parse("== 1").is_err());
        assert!(Expect::parse("< nan").is_err());
    }
}
