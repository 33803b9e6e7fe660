//! Evaluating paper claims (`scenario::claims`) against runs: our figure next to the paper's.

use crate::record::RunRecord;
use crate::scenario::claims::{Aggregate, Claim, Expect, Measure};

/// Runs of one scenario.
pub struct ScenarioRuns<'a> {
    pub scenario: &'a str,
    pub runs: &'a [RunRecord],
}

/// One claim and what we measured.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The scenario that states the claim.
    pub scenario: String,
    pub claim: Claim,
    /// Our values, each labelled by its case (one value, labelled by the aggregate, unless the
    /// aggregate is `each`); or why there is none.
    pub measured: Result<Vec<(String, f64)>, String>,
    /// Whether every value meets `expect`; `None` without `expect` or without a value.
    pub holds: Option<bool>,
}

/// Evaluates every claim of `claims` (stated by `scenario`) over `all` runs: the runs of every
/// scenario of the execution. A measure takes the runs of `scenario` unless its `where` names
/// another, so a claim may compare runs of different scenarios run together.
pub fn evaluate(scenario: &str, claims: &[Claim], all: &[ScenarioRuns]) -> Vec<Outcome> {
    claims
        .iter()
        .map(|c| {
            let measured = measure(&c.measure, scenario, all);
            let holds = match (&c.expect, &measured) {
                (Some(e), Ok(values)) => Expect::parse(e)
                    .ok()
                    .map(|e| values.iter().all(|&(_, v)| e.holds(v))),
                _ => None,
            };
            Outcome {
                scenario: scenario.to_string(),
                claim: c.clone(),
                measured,
                holds,
            }
        })
        .collect()
}

fn measure(
    m: &Measure,
    stated_by: &str,
    all: &[ScenarioRuns],
) -> Result<Vec<(String, f64)>, String> {
    let mut values = Vec::new();
    // Without `where.scenario`, only the runs of the scenario stating the claim.
    let own_only = !m.select.contains_key("scenario");
    for set in all
        .iter()
        .filter(|set| !own_only || set.scenario == stated_by)
    {
        for r in set.runs.iter().filter(|r| r.failure.is_none()) {
            let json = serde_json::to_value(r).expect("records serialize");
            if matches(&m.select, set.scenario, &json) {
                let v = figure(&m.figure, &json).ok_or_else(|| {
                    format!("a matching run ({}) has no {}", r.case_id(), m.figure)
                })?;
                values.push((format!("{} {}", set.scenario, r.case_id()), v));
            }
        }
    }
    if values.is_empty() {
        if let Some(name) = m.select.get("scenario").and_then(|v| v.as_str()) {
            if !all.iter().any(|s| s.scenario == name) {
                return Err(format!(
                    "the runs of scenario '{name}' are not in these results (run it together \
                     with this one)"
                ));
            }
        }
        return Err("no finished run matches".into());
    }
    let one = |label: &str, v: f64| Ok(vec![(label.to_string(), v)]);
    let numerator = match m.aggregate {
        Aggregate::Each => return Ok(values),
        Aggregate::Mean => values.iter().map(|v| v.1).sum::<f64>() / values.len() as f64,
        Aggregate::Min => values.iter().map(|v| v.1).fold(f64::INFINITY, f64::min),
        Aggregate::Max => values.iter().map(|v| v.1).fold(f64::NEG_INFINITY, f64::max),
        Aggregate::Sum => values.iter().map(|v| v.1).sum(),
    };
    let label = format!("{:?} of {}", m.aggregate, values.len()).to_lowercase();
    match &m.over {
        None => one(&label, numerator),
        Some(over) => {
            let denominator = measure(over, stated_by, all).map_err(|e| format!("over: {e}"))?[0].1;
            if denominator == 0.0 {
                return Err("the `over` figure is 0".into());
            }
            one(&format!("ratio of {label}"), numerator / denominator)
        }
    }
}

/// Whether the run `json` of `scenario` has every field of `select`.
fn matches(
    select: &std::collections::BTreeMap<String, serde_json::Value>,
    scenario: &str,
    json: &serde_json::Value,
) -> bool {
    select.iter().all(|(key, want)| {
        let have = match key.as_str() {
            "scenario" => serde_json::Value::from(scenario),
            k => json
                .get(k)
                .or_else(|| json["params"].get(k))
                .cloned()
                .unwrap_or(serde_json::Value::Null),
        };
        same(&have, want)
    })
}

/// JSON equality with numbers compared to single precision (parameters are `f32`).
fn same(a: &serde_json::Value, b: &serde_json::Value) -> bool {
    match (a, b) {
        (serde_json::Value::Number(x), serde_json::Value::Number(y)) => {
            let (x, y) = (
                x.as_f64().unwrap_or(f64::NAN),
                y.as_f64().unwrap_or(f64::NAN),
            );
            (x - y).abs() <= 1e-6 * x.abs().max(y.abs()).max(1.0)
        }
        (serde_json::Value::Array(x), serde_json::Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| same(x, y))
        }
        _ => a == b,
    }
}

/// The figure `name` of the run `json` (see `Measure::figure`).
fn figure(name: &str, json: &serde_json::Value) -> Option<f64> {
    if let Some(path) = name.strip_prefix("per_second.") {
        return figure(path, json).filter(|&v| v > 0.0).map(|v| 1e3 / v);
    }
    if let Some(rest) = name.strip_prefix("phase_share.") {
        let (phase, time) = rest.rsplit_once('.')?;
        let phases = json["phases"].as_array()?;
        let total: f64 = phases.iter().filter_map(|p| p[time].as_f64()).sum();
        // `a+b`: the phases' times together.
        let mine = phase
            .split('+')
            .map(|name| {
                phases
                    .iter()
                    .find(|p| p["name"] == name)
                    .and_then(|p| p[time].as_f64())
            })
            .sum::<Option<f64>>()?;
        return (total > 0.0).then(|| mine / total);
    }
    // Counter names contain dots (`mem_est.gbuffer.read_bytes`): after `counters.` the rest is
    // one key, or several joined by `+` (their sum; absent unless every one is present).
    if let Some(counters) = name.strip_prefix("counters.") {
        return counters
            .split('+')
            .map(|c| json["counters"].get(c)?.as_f64())
            .sum();
    }
    name.split('.')
        .try_fold(json, |v, key| v.get(key))?
        .as_f64()
        .filter(|v| v.is_finite())
}

/// The claims as a text table (for the terminal).
pub fn render_text(outcomes: &[Outcome]) -> String {
    let mut s = String::new();
    for o in outcomes {
        let c = &o.claim;
        s.push_str(&format!("[{}] {}\n", c.paper, c.claim));
        s.push_str(&format!(
            "    paper: {}   ours: {}   {}\n",
            c.paper_value.as_deref().unwrap_or("-"),
            ours(o),
            verdict(o)
        ));
    }
    s
}

/// Our figure(s) of an outcome, or why there is none.
pub fn ours(o: &Outcome) -> String {
    match &o.measured {
        Ok(values) if values.len() == 1 => super::fmt_num(values[0].1),
        Ok(values) => values
            .iter()
            .map(|(label, v)| format!("{label}: {}", super::fmt_num(*v)))
            .collect::<Vec<_>>()
            .join("; "),
        Err(e) => format!("not measured ({e})"),
    }
}

/// `holds (expect …)`, `does not hold (expect …)` or `-`.
pub fn verdict(o: &Outcome) -> String {
    match (o.holds, &o.claim.expect) {
        (Some(true), Some(e)) => format!("holds (expect {e})"),
        (Some(false), Some(e)) => format!("DOES NOT HOLD (expect {e})"),
        _ => "-".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::Backend;
    use crate::report::testdata::record;

    fn claim(json: serde_json::Value) -> Claim {
        serde_json::from_value(json).unwrap()
    }

    #[test]
    fn measures_select_aggregate_and_divide() {
        let mut a = record("soft_izb", Backend::CpuModel, 1000, 16);
        a.model_ms = Some(20.0);
        a.counters.set("fill", 300.0);
        let mut b = record("pcss", Backend::CpuModel, 1000, 16);
        b.model_ms = Some(40.0);
        b.counters.set("fill", 100.0);
        let mut c = record("soft_izb", Backend::CpuModel, 1000, 16);
        c.model_ms = Some(10.0);
        let runs = [a, b];
        let others = [c];
        // A claim of "s" takes only the runs of "s" unless it names another scenario.
        let all = [
            ScenarioRuns {
                scenario: "s",
                runs: &runs,
            },
            ScenarioRuns {
                scenario: "t",
                runs: &others,
            },
        ];
        let fps = claim(serde_json::json!({
            "paper": "p", "claim": "c", "expect": "> 49",
            "measure": { "figure": "per_second.model_ms", "where": { "algorithm": "soft_izb" } }
        }));
        let ratio = claim(serde_json::json!({
            "paper": "p", "claim": "c", "expect": "< 2",
            "measure": { "figure": "counters.fill", "aggregate": "sum",
                         "where": { "algorithm": "soft_izb", "tile_size": 16 },
                         "over": { "figure": "counters.fill", "aggregate": "mean",
                                   "where": { "scenario": "s", "backend": "cpu-model" } } }
        }));
        let share = claim(serde_json::json!({
            "paper": "p", "claim": "c",
            "measure": { "figure": "phase_share.soft.model_ms", "where": { "backend": "cpu-model" } }
        }));
        let both = claim(serde_json::json!({
            "paper": "p", "claim": "c", "expect": "> 0.99",
            "measure": { "figure": "phase_share.construct+soft.wall_ms",
                         "where": { "backend": "cpu-model" }, "aggregate": "min" }
        }));
        let none = claim(serde_json::json!({
            "paper": "p", "claim": "c", "expect": "> 0",
            "measure": { "figure": "model_ms", "where": { "backend": "wgpu" } }
        }));
        let out = evaluate("s", &[fps, ratio, share, none, both], &all);
        assert_eq!(
            out[0].measured.as_ref().unwrap(),
            &[(
                "s sphere-on-plane_soft_izb_cpu-model_t1000_l0.5_m512_b16_96x72".to_string(),
                50.0
            )]
        );
        assert_eq!(out[0].holds, Some(true));
        // 300 / mean(300, 100) = 1.5
        assert_eq!(out[1].measured.as_ref().unwrap()[0].1, 1.5);
        assert_eq!(out[1].holds, Some(true));
        // Phases of 0.4 and 0.6 modelled ms; `each` lists both runs.
        let shares = out[2].measured.as_ref().unwrap();
        assert_eq!(shares.len(), 2);
        assert!(shares.iter().all(|(_, v)| (v - 0.6).abs() < 1e-12));
        assert!(out[3].measured.is_err() && out[3].holds.is_none());
        // Phases of 1 and 2 wall ms together: the whole frame.
        assert_eq!(out[4].measured.as_ref().unwrap()[0].1, 1.0);
        assert_eq!(out[4].holds, Some(true));
    }

    #[test]
    fn a_sum_of_counters_needs_every_one() {
        let mut a = record("accum_hard", Backend::Wgpu, 1000, 16);
        a.counters.set("mem_est.depth.read_bytes", 30.0);
        a.counters.set("mem_est.stencil.read_bytes", 70.0);
        let runs = [a];
        let all = [ScenarioRuns {
            scenario: "s",
            runs: &runs,
        }];
        let sum = |figure: &str| {
            claim(serde_json::json!({
                "paper": "p", "claim": "c", "expect": "> 0",
                "measure": { "figure": figure, "aggregate": "sum" }
            }))
        };
        let out = evaluate(
            "s",
            &[
                sum("counters.mem_est.depth.read_bytes+mem_est.stencil.read_bytes"),
                sum("counters.mem_est.depth.read_bytes+mem_est.vbuffer.read_bytes"),
            ],
            &all,
        );
        assert_eq!(out[0].measured.as_ref().unwrap()[0].1, 100.0);
        // A part the run lacks: no figure, not a partial sum.
        assert!(out[1].measured.is_err() && out[1].holds.is_none());
    }
}
