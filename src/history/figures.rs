//! The figures of a run record, flattened to named values for the history store.
//!
//! The store is generic over what a record holds: every number of the record's JSON outside
//! its identity (`algorithm`, `backend`, `scene`, `light`, `params`), its conditions
//! (`execution`, `framing`) and its messages (`warnings`, `failure`) is a figure, named by its
//! path: `counters.fill`, `error.mae_shadow`, `model_ms`, `wall_ms`, `phase.<name>.model_ms`,
//! `phase.<name>.counters.<counter>` (a phase name used twice gets `#2`, `#3`, as `compare`
//! names them). Figures added to records later are recorded without a change here.
//!
//! A measured figure may come with its spread, in either of two shapes:
//!
//! - an object with a `median` (or `value`) and any of `samples` (numbers), `ci95` / `ci`
//!   (`[lower, upper]`) or `lower` / `upper`: the figure is the median, its interval the one
//!   given, its samples kept;
//! - beside a number `X`, an array `X_samples` of numbers: the samples of `X`.
//!
//! Failed runs have no figures. Non-finite numbers (written as `null`) are skipped.

use serde_json::{Map, Value};

use crate::record::RunRecord;

/// One value of a figure in one run: the value, a confidence interval where the record gives
/// one (or one computed from its samples), and the samples themselves.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    pub value: f64,
    pub lower: Option<f64>,
    pub upper: Option<f64>,
    pub samples: Vec<f64>,
}

impl Point {
    /// A value without spread.
    pub fn exact(value: f64) -> Point {
        Point {
            value,
            lower: None,
            upper: None,
            samples: vec![],
        }
    }

    /// The standard deviation of the value itself, from its interval (taken as a 95%
    /// interval: half-width / 1.96) or else from its samples (1.4826 × MAD / √n, the standard
    /// error of a median of normal samples up to the factor √(π/2) ≈ 1.25, applied in
    /// [`super::detect`]); 0 when the record gives no spread.
    pub fn sigma(&self) -> f64 {
        if let (Some(lo), Some(hi)) = (self.lower, self.upper) {
            return ((hi - lo) / 2.0 / 1.96).max(0.0);
        }
        if self.samples.len() >= 2 {
            let n = self.samples.len() as f64;
            return 1.4826 * mad(&self.samples) / n.sqrt();
        }
        0.0
    }
}

/// The median of `v` (NaN-free); 0 for an empty slice.
pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        (s[n / 2 - 1] + s[n / 2]) / 2.0
    }
}

/// The median absolute deviation from the median.
pub fn mad(v: &[f64]) -> f64 {
    let m = median(v);
    let d: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    median(&d)
}

/// Top-level fields of a record that are not figures.
const NOT_FIGURES: [&str; 9] = [
    "algorithm",
    "backend",
    "scene",
    "light",
    "params",
    "execution",
    "framing",
    "warnings",
    "failure",
];

/// The figures of `r`, by name, sorted; none for a failed run.
pub fn of_record(r: &RunRecord) -> Vec<(String, Point)> {
    if r.failure.is_some() {
        return vec![];
    }
    let Ok(Value::Object(top)) = serde_json::to_value(r) else {
        return vec![];
    };
    let mut out = Vec::new();
    for (k, v) in &top {
        if NOT_FIGURES.contains(&k.as_str()) {
            continue;
        }
        if k == "phases" {
            let mut used: Vec<String> = Vec::new();
            for p in v.as_array().into_iter().flatten() {
                let Some(obj) = p.as_object() else { continue };
                let name = obj.get("name").and_then(Value::as_str).unwrap_or("?");
                let mut label = format!("phase.{name}");
                let mut k = 2;
                while used.contains(&label) {
                    label = format!("phase.{name}#{k}");
                    k += 1;
                }
                used.push(label.clone());
                let mut rest = obj.clone();
                rest.remove("name");
                flatten_object(&label, &rest, &mut out);
            }
            continue;
        }
        flatten(k, v, &top, &mut out);
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out.dedup_by(|a, b| a.0 == b.0);
    out
}

fn flatten_object(prefix: &str, obj: &Map<String, Value>, out: &mut Vec<(String, Point)>) {
    for (k, v) in obj {
        flatten(&format!("{prefix}.{k}"), v, obj, out);
    }
}

/// Adds the figure(s) at `name` with value `v`; `siblings` is the object holding it (for
/// `X_samples` arrays).
fn flatten(name: &str, v: &Value, siblings: &Map<String, Value>, out: &mut Vec<(String, Point)>) {
    let leaf = name.rsplit('.').next().unwrap_or(name);
    match v {
        Value::Number(n) => {
            let Some(x) = n.as_f64().filter(|x| x.is_finite()) else {
                return;
            };
            let mut p = Point::exact(x);
            if let Some(s) = siblings.get(&format!("{leaf}_samples")).and_then(numbers) {
                p.samples = s;
            }
            out.push((name.to_string(), p));
        }
        Value::Array(_) if leaf.ends_with("_samples") => {
            // Samples of a number beside it; alone, they stand for their median.
            let base = leaf.trim_end_matches("_samples");
            if !siblings.contains_key(base) {
                if let Some(s) = numbers(v).filter(|s| !s.is_empty()) {
                    let figure = format!("{}{base}", &name[..name.len() - leaf.len()]);
                    out.push((
                        figure,
                        Point {
                            value: median(&s),
                            lower: None,
                            upper: None,
                            samples: s,
                        },
                    ));
                }
            }
        }
        Value::Object(obj) => {
            if let Some(p) = measured(obj) {
                out.push((name.to_string(), p));
            } else {
                flatten_object(name, obj, out);
            }
        }
        _ => {}
    }
}

/// Every element of `v` as a finite number, or `None`.
fn numbers(v: &Value) -> Option<Vec<f64>> {
    v.as_array()?
        .iter()
        .map(|x| x.as_f64().filter(|x| x.is_finite()))
        .collect()
}

/// A measured figure's object: its median (or value) with samples and an interval.
fn measured(obj: &Map<String, Value>) -> Option<Point> {
    let value = obj
        .get("median")
        .or_else(|| obj.get("value"))?
        .as_f64()
        .filter(|x| x.is_finite())?;
    let samples = obj.get("samples").and_then(numbers).unwrap_or_default();
    let pair = |k: &str| {
        let a = numbers(obj.get(k)?)?;
        (a.len() == 2).then(|| (a[0], a[1]))
    };
    let (lower, upper) = match pair("ci95").or_else(|| pair("ci")) {
        Some((lo, hi)) => (Some(lo), Some(hi)),
        None => (
            obj.get("lower").and_then(Value::as_f64),
            obj.get("upper").and_then(Value::as_f64),
        ),
    };
    Some(Point {
        value,
        lower,
        upper,
        samples,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::Backend;
    use crate::report::testdata::record;

    #[test]
    fn every_number_outside_identity_and_conditions_is_a_figure() {
        let r = record("pcss", Backend::CpuModel, 500, 32);
        let f = of_record(&r);
        let names: Vec<&str> = f.iter().map(|(n, _)| n.as_str()).collect();
        // Identity and conditions are not figures.
        assert!(!names
            .iter()
            .any(|n| n.starts_with("params") || n.starts_with("execution")));
        for c in r.counters.0.keys() {
            assert!(names.contains(&format!("counters.{c}").as_str()), "{c}");
        }
        let model = f.iter().find(|(n, _)| n == "model_ms").unwrap();
        assert_eq!(model.1.value, r.model_ms.unwrap());
        assert!(names.contains(&"wall_ms"));
        assert!(names.contains(&"error.mae_shadow"));
        for p in &r.phases {
            assert!(
                names
                    .iter()
                    .any(|n| n.starts_with(&format!("phase.{}.", p.name))),
                "{}",
                p.name
            );
        }
        let mut failed = r.clone();
        failed.failure = Some("x".into());
        assert!(of_record(&failed).is_empty());
    }

    #[test]
    fn measured_shapes_keep_their_samples_and_interval() {
        let obj: Map<String, Value> = serde_json::from_str(
            r#"{"gpu": {"median": 2.0, "samples": [1.9, 2.0, 2.3], "ci95": [1.9, 2.3]},
                "wall_ms": 5.0, "wall_ms_samples": [4.0, 5.0, 6.0],
                "cold_ms_samples": [7.0, 9.0, 8.0]}"#,
        )
        .unwrap();
        let mut out = Vec::new();
        flatten_object("phase.x", &obj, &mut out);
        out.sort_by(|a, b| a.0.cmp(&b.0));
        let get = |n: &str| out.iter().find(|(k, _)| k == n).unwrap().1.clone();
        let gpu = get("phase.x.gpu");
        assert_eq!(
            (gpu.value, gpu.lower, gpu.upper),
            (2.0, Some(1.9), Some(2.3))
        );
        assert_eq!(gpu.samples, vec![1.9, 2.0, 2.3]);
        assert!((gpu.sigma() - 0.4 / 2.0 / 1.96).abs() < 1e-12);
        let wall = get("phase.x.wall_ms");
        assert_eq!(wall.value, 5.0);
        assert_eq!(wall.samples, vec![4.0, 5.0, 6.0]);
        // MAD 1 of 3 samples: 1.4826 / sqrt(3).
        assert!((wall.sigma() - 1.4826 / 3f64.sqrt()).abs() < 1e-12);
        assert_eq!(get("phase.x.cold_ms").value, 8.0);
        assert_eq!(out.len(), 3, "{out:?}");
    }
}
