//! The regression gate: compares the deterministic figures of two result sets run by run.
//!
//! Every figure's kind and direction come from one table, the glossary
//! ([`crate::counters::figure`]): counters, times and quality metrics each say whether they are
//! deterministic, modelled, measured or estimated, and whether lower or higher is better.
//! Nothing is read from a figure's name; a figure the glossary does not hold is listed as not
//! judged.
//!
//! Which figures are compared (the same input gives the same number on any host):
//!
//! - `cpu-model` runs: every counter, `model_ms`, each phase's `model_ms` and counters, and the
//!   quality metrics `error.{mae,rmse,max,mae_shadow,frac_over_0_1}`.
//! - `cpu-native` runs: every counter, each phase's counters and the quality metrics (the host
//!   kernels are seeded and independent of the thread count).
//! - `wgpu` runs and any other backend: no figure. Their counters (pipeline statistics) and
//!   images depend on the adapter and driver, so only whether the run is present and succeeded
//!   is checked.
//!
//! Measured figures (wall-clock and GPU times) are not compared here.
//!
//! A run fails the gate when a figure worsens (in its glossary direction) by more than the
//! threshold (in percent of the baseline; any worsening from zero counts as infinite), when a
//! baseline run is missing from the current results, or when a run that succeeded now fails. A
//! derived ratio ([`crate::counters::parts`]) is judged with its parts: it fails the gate only
//! when one of its parts worsened too (`overdraw_ratio` rising because `fill` fell is listed as
//! worse, not gated). A baseline with no runs is refused as an input error: a gate that
//! compared nothing must not pass. Figures that appear or disappear are listed but do not fail it.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use super::fmt_num;
use crate::backend::Backend;
use crate::counters::{Direction, Kind};
use crate::error::InputError;
use crate::harness::output::ResultsFile;
use crate::record::RunRecord;

/// The default threshold of `shadowbench compare`, in percent.
pub const DEFAULT_THRESHOLD_PCT: f64 = 2.0;

/// How `compare` judges: the threshold of deterministic figures, thresholds of single figures
/// (`--threshold-for FIGURE=PCT`: a deterministic figure's threshold, a measured figure's
/// minimum effect), the minimum effect and false-discovery rate of measured figures, and
/// whether measured regressions fail the gate (`--gate measured`).
#[derive(Clone, Debug)]
pub struct Options {
    pub threshold_pct: f64,
    /// By glossary name (`fill`, `gpu_ms`, `mem_model.<buffer>.read_bytes`) or by figure name
    /// as compared (`phase.soft.fill`).
    pub per_figure: BTreeMap<String, f64>,
    pub min_effect_pct: f64,
    pub q: f64,
    pub gate_measured: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            threshold_pct: DEFAULT_THRESHOLD_PCT,
            per_figure: BTreeMap::new(),
            min_effect_pct: super::measured::DEFAULT_MIN_EFFECT_PCT,
            q: super::measured::DEFAULT_Q,
            gate_measured: false,
        }
    }
}

impl Options {
    /// The threshold of `figure`: its own (by figure name, then glossary name), or `default`.
    pub fn threshold_of(&self, figure: &str, default: f64) -> f64 {
        self.per_figure
            .get(figure)
            .or_else(|| crate::counters::figure(figure).and_then(|c| self.per_figure.get(c.name)))
            .copied()
            .unwrap_or(default)
    }

    /// Parses `--threshold-for FIGURE=PCT` values into `per_figure`: each figure must be in
    /// the glossary and each percentage a number ≥ 0.
    pub fn set_per_figure(&mut self, values: &[String]) -> Result<(), InputError> {
        for v in values {
            let bad = |why: String| InputError::new("--threshold-for", format!("'{v}': {why}"));
            let (name, pct) = v
                .split_once('=')
                .ok_or_else(|| bad("expected FIGURE=PERCENT".into()))?;
            let known = crate::counters::COUNTERS
                .iter()
                .chain(crate::counters::FIGURES)
                .any(|c| c.name == name)
                || crate::counters::figure(name).is_some();
            if !known {
                return Err(bad(format!(
                    "'{name}' is not a figure of the glossary (shadowbench list --counters)"
                )));
            }
            let pct: f64 = pct
                .parse()
                .map_err(|_| bad(format!("'{pct}' is not a number")))?;
            self.per_figure.insert(
                name.to_string(),
                check_threshold(pct).map_err(|e| bad(e.message))?,
            );
        }
        Ok(())
    }
}

/// The figures of a successful run that `compare` judges, by name (see the module docs): its
/// figures whose glossary kind is not measured, modelled ones of cpu-model runs only. Figures
/// the glossary does not hold are kept, so the comparison can list them as not judged.
pub fn deterministic_figures(r: &RunRecord) -> BTreeMap<String, f64> {
    let mut f = BTreeMap::new();
    let model = match r.backend {
        Backend::CpuModel => true,
        Backend::CpuNative => false,
        Backend::Wgpu => return f,
    };
    // Older results name memory traffic differently: compared under the current names.
    let current = |k: &str| crate::counters::current_name(r.backend, k).into_owned();
    for (k, v) in &r.counters.0 {
        f.insert(format!("counters.{}", current(k)), *v);
    }
    if let Some(v) = r.model_ms {
        f.insert("model_ms".into(), v);
    }
    f.insert("wall_ms".into(), r.wall_ms);
    if let Some(v) = r.gpu_ms {
        f.insert("gpu_ms".into(), v);
    }
    for p in &r.phases {
        let mut name = format!("phase.{}", p.name);
        let mut k = 2;
        while f.keys().any(|key| key.starts_with(&format!("{name}."))) {
            name = format!("phase.{}#{k}", p.name);
            k += 1;
        }
        if let Some(v) = p.model_ms {
            f.insert(format!("{name}.model_ms"), v);
        }
        f.insert(format!("{name}.wall_ms"), p.wall_ms);
        for (c, v) in &p.counters.0 {
            f.insert(format!("{name}.{}", current(c)), *v);
        }
    }
    if let Some(e) = &r.error {
        for (k, v) in e.named() {
            if let Some(v) = v {
                f.insert(format!("error.{k}"), v);
            }
        }
    }
    if let Some(v) = r.animation.as_ref().and_then(|a| a.flicker) {
        f.insert("animation.flicker".into(), v);
    }
    f.retain(|name, _| match crate::counters::kind(name) {
        Some(Kind::Measured) => false,
        Some(Kind::Modelled) => model,
        Some(Kind::Deterministic | Kind::Estimated) | None => true,
    });
    f
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Verdict {
    /// Worse by more than the threshold.
    Regression,
    /// Worse, within the threshold.
    Worse,
    Better,
}

/// A figure that moved.
#[derive(Clone, Debug, PartialEq)]
pub struct Change {
    pub verdict: Verdict,
    pub case: String,
    pub figure: String,
    pub old: f64,
    pub new: f64,
    /// Why a worsening beyond the threshold does not gate (a derived ratio whose parts did not
    /// worsen).
    pub note: Option<String>,
}

impl Change {
    /// Change in percent of the old value; infinite when the old value is zero.
    pub fn pct(&self) -> f64 {
        if self.old == 0.0 {
            f64::INFINITY.copysign(self.new)
        } else {
            (self.new - self.old) / self.old.abs() * 100.0
        }
    }
}

/// What happened to a run as a whole.
#[derive(Clone, Debug, PartialEq)]
pub enum RunStatus {
    /// In the baseline, not in the current results.
    Missing,
    /// Succeeded in the baseline, fails now (with the failure).
    NewlyFailed(String),
    /// Failed in the baseline, succeeds now.
    Fixed,
    /// Only in the current results.
    Added,
}

impl RunStatus {
    fn fails_gate(&self) -> bool {
        matches!(self, RunStatus::Missing | RunStatus::NewlyFailed(_))
    }
}

#[derive(Debug)]
pub struct Comparison {
    pub threshold_pct: f64,
    /// The measured figures' tests, in their own table.
    pub measured: super::measured::MeasuredComparison,
    /// Whether measured regressions fail the gate.
    pub gate_measured: bool,
    /// Runs whose figures were compared.
    pub runs_compared: usize,
    pub figures_compared: usize,
    /// Regressions first, then worse, then better.
    pub changes: Vec<Change>,
    pub runs: Vec<(String, RunStatus)>,
    /// Figure names only in the baseline, with how many runs.
    pub dropped: BTreeMap<String, usize>,
    /// Figure names only in the current results, with how many runs.
    pub added: BTreeMap<String, usize>,
    /// Figure names the glossary does not hold, so not judged, with how many runs.
    pub unjudged: BTreeMap<String, usize>,
    /// The scenario names (baseline, current) when they differ.
    pub scenarios_differ: Option<(String, String)>,
}

impl Comparison {
    /// Whether the gate fails.
    pub fn regressed(&self) -> bool {
        self.changes
            .iter()
            .any(|c| c.verdict == Verdict::Regression)
            || self.runs.iter().any(|(_, s)| s.fails_gate())
            || (self.gate_measured && self.measured.regressions() > 0)
    }

    /// The measured figures' table and summary ([`super::measured`]), and whether they gate.
    pub fn render_measured(&self) -> String {
        let mut s = self.measured.render();
        if !self.gate_measured && self.measured.regressions() > 0 {
            let _ = writeln!(
                s,
                "note: measured regressions do not fail the gate without --gate measured"
            );
        }
        s
    }

    /// The table of what moved, and the verdict.
    pub fn render(&self) -> String {
        let mut s = String::new();
        if let Some((old, new)) = &self.scenarios_differ {
            let _ = writeln!(
                s,
                "note: different scenarios: baseline '{old}', current '{new}'; runs are \
                 matched by their case id only"
            );
        }
        if !self.changes.is_empty() {
            let rows: Vec<[String; 6]> = self
                .changes
                .iter()
                .map(|c| {
                    [
                        match c.verdict {
                            Verdict::Regression => "REGRESSION",
                            Verdict::Worse => "worse",
                            Verdict::Better => "better",
                        }
                        .to_string(),
                        c.case.clone(),
                        c.figure.clone(),
                        fmt_num(c.old),
                        fmt_num(c.new),
                        format!("{:+.2}%", c.pct()),
                    ]
                })
                .collect();
            let head = ["", "run", "figure", "baseline", "current", "change"];
            let mut w = head.map(str::len);
            for r in &rows {
                for (i, c) in r.iter().enumerate() {
                    w[i] = w[i].max(c.chars().count());
                }
            }
            let notes = std::iter::once(None).chain(self.changes.iter().map(|c| c.note.as_ref()));
            for (r, note) in std::iter::once(head.map(String::from))
                .chain(rows)
                .zip(notes)
            {
                let _ = write!(
                    s,
                    "{:<w0$}  {:<w1$}  {:<w2$}  {:>w3$}  {:>w4$}  {:>w5$}",
                    r[0],
                    r[1],
                    r[2],
                    r[3],
                    r[4],
                    r[5],
                    w0 = w[0],
                    w1 = w[1],
                    w2 = w[2],
                    w3 = w[3],
                    w4 = w[4],
                    w5 = w[5]
                );
                let _ = match note {
                    Some(n) => writeln!(s, "  ({n})"),
                    None => writeln!(s),
                };
            }
        }
        for (case, status) in &self.runs {
            let _ = match status {
                RunStatus::Missing => writeln!(s, "MISSING     {case}: in the baseline only"),
                RunStatus::NewlyFailed(f) => writeln!(s, "FAILS NOW   {case}: {f}"),
                RunStatus::Fixed => writeln!(s, "fixed       {case}: failed in the baseline"),
                RunStatus::Added => writeln!(s, "new         {case}: not in the baseline"),
            };
        }
        for (what, map) in [
            ("baseline", &self.dropped),
            ("current results", &self.added),
        ] {
            for (figure, n) in map {
                let _ = writeln!(s, "note: {figure} only in the {what} ({n} runs)");
            }
        }
        for (figure, n) in &self.unjudged {
            let _ = writeln!(
                s,
                "note: {figure} is not in the glossary, so not judged ({n} runs)"
            );
        }
        s.push_str(&self.render_measured());
        let count = |v: Verdict| self.changes.iter().filter(|c| c.verdict == v).count();
        let _ = writeln!(
            s,
            "{}: {} runs, {} figures compared; {} regressions beyond {}%, {} worse within it, {} better; {} runs missing, {} newly failing",
            if self.regressed() { "FAIL" } else { "PASS" },
            self.runs_compared,
            self.figures_compared,
            count(Verdict::Regression),
            self.threshold_pct,
            count(Verdict::Worse),
            count(Verdict::Better),
            self.runs.iter().filter(|(_, s)| *s == RunStatus::Missing).count(),
            self.runs
                .iter()
                .filter(|(_, s)| matches!(s, RunStatus::NewlyFailed(_)))
                .count(),
        );
        s
    }
}

/// The runs of a results file by case id; two runs of one case is an error naming the file
/// (the rule [`crate::report::read_results`] applies to every input).
fn by_case<'a>(
    path: &Path,
    file: &'a ResultsFile,
) -> Result<BTreeMap<String, &'a RunRecord>, InputError> {
    file.check_runs().map_err(|e| e.in_file(path))?;
    Ok(file.runs.iter().map(|r| (r.case_id(), r)).collect())
}

/// Checks a `--threshold` value.
pub fn check_threshold(pct: f64) -> Result<f64, InputError> {
    if pct.is_finite() && pct >= 0.0 {
        Ok(pct)
    } else {
        Err(InputError::new(
            "--threshold",
            format!("expected a percentage ≥ 0, got {pct}"),
        ))
    }
}

/// Compares `current` against `baseline` (paths name them in errors).
pub fn compare(
    baseline: (&Path, &ResultsFile),
    current: (&Path, &ResultsFile),
    options: &Options,
) -> Result<Comparison, InputError> {
    let threshold_pct = check_threshold(options.threshold_pct)?;
    if baseline.1.runs.is_empty() {
        // A gate that compared nothing must not pass.
        return Err(InputError {
            file: Some(baseline.0.to_path_buf()),
            field: Some("$.runs".into()),
            message: "the baseline has no runs, so nothing would be compared".into(),
        });
    }
    let old = by_case(baseline.0, baseline.1)?;
    let new = by_case(current.0, current.1)?;
    let mut cmp = Comparison {
        threshold_pct,
        measured: Default::default(),
        gate_measured: options.gate_measured,
        runs_compared: 0,
        figures_compared: 0,
        changes: Vec::new(),
        runs: Vec::new(),
        dropped: BTreeMap::new(),
        added: BTreeMap::new(),
        unjudged: BTreeMap::new(),
        scenarios_differ: (baseline.1.scenario != current.1.scenario)
            .then(|| (baseline.1.scenario.clone(), current.1.scenario.clone())),
    };
    for (case, o) in &old {
        let Some(n) = new.get(case) else {
            cmp.runs.push((case.clone(), RunStatus::Missing));
            continue;
        };
        match (&o.failure, &n.failure) {
            (None, Some(f)) => cmp
                .runs
                .push((case.clone(), RunStatus::NewlyFailed(f.clone()))),
            (Some(_), None) => cmp.runs.push((case.clone(), RunStatus::Fixed)),
            (Some(_), Some(_)) => {}
            (None, None) => {
                cmp.runs_compared += 1;
                compare_run(&mut cmp, options, case, o, n);
            }
        }
    }
    let pairs = old.iter().filter_map(|(case, o)| {
        let n = new.get(case)?;
        Some((case.as_str(), *o, *n))
    });
    cmp.measured = super::measured::MeasuredComparison::of(pairs, options.q, |f| {
        options.threshold_of(f, options.min_effect_pct)
    });
    for case in new.keys().filter(|c| !old.contains_key(*c)) {
        cmp.runs.push((case.clone(), RunStatus::Added));
    }
    cmp.changes
        .sort_by(|a, b| (a.verdict, &a.case, &a.figure).cmp(&(b.verdict, &b.case, &b.figure)));
    Ok(cmp)
}

fn compare_run(cmp: &mut Comparison, options: &Options, case: &str, o: &RunRecord, n: &RunRecord) {
    let (fo, fnew) = (deterministic_figures(o), deterministic_figures(n));
    let first = cmp.changes.len();
    for (figure, &old) in &fo {
        let Some(&new) = fnew.get(figure) else {
            *cmp.dropped.entry(figure.clone()).or_default() += 1;
            continue;
        };
        let Some(direction) = crate::counters::direction(figure) else {
            *cmp.unjudged.entry(figure.clone()).or_default() += 1;
            continue;
        };
        cmp.figures_compared += 1;
        if new == old || (new.is_nan() && old.is_nan()) {
            continue;
        }
        let worse = match direction {
            Direction::Higher => new < old,
            Direction::Lower => new > old,
        } || new.is_nan();
        let mut change = Change {
            verdict: Verdict::Better,
            case: case.to_string(),
            figure: figure.clone(),
            old,
            new,
            note: None,
        };
        if worse {
            let pct = change.pct().abs();
            let threshold = options.threshold_of(figure, cmp.threshold_pct);
            change.verdict = if pct > threshold || pct.is_nan() {
                Verdict::Regression
            } else {
                Verdict::Worse
            };
        }
        cmp.changes.push(change);
    }
    judge_ratios_with_their_parts(&mut cmp.changes[first..], |f| {
        fo.contains_key(f) && fnew.contains_key(f)
    });
    for figure in fnew.keys().filter(|f| !fo.contains_key(*f)) {
        *cmp.added.entry(figure.clone()).or_default() += 1;
    }
}

/// A derived ratio's regression stands only when one of its parts (in the same record or
/// phase) worsened too; otherwise it moved because a part improved, and it is listed as worse
/// with a note naming the parts. A ratio whose parts are not both in the two records (`both`)
/// stands on its own.
fn judge_ratios_with_their_parts(changes: &mut [Change], both: impl Fn(&str) -> bool) {
    let worse: Vec<String> = changes
        .iter()
        .filter(|c| c.verdict != Verdict::Better)
        .map(|c| c.figure.clone())
        .collect();
    for c in changes
        .iter_mut()
        .filter(|c| c.verdict == Verdict::Regression)
    {
        let Some((prefix, [num, den])) = crate::counters::DERIVED.iter().find_map(|d| {
            let prefix = c.figure.strip_suffix(d)?.strip_suffix('.')?;
            Some((prefix.to_string(), crate::counters::parts(d)?))
        }) else {
            continue;
        };
        let [num_f, den_f] = [num, den].map(|p| format!("{prefix}.{p}"));
        if !(both(&num_f) && both(&den_f)) {
            continue;
        }
        if !worse.contains(&num_f) && !worse.contains(&den_f) {
            c.verdict = Verdict::Worse;
            c.note = Some(format!(
                "judged with its parts: neither {num} nor {den} worsened"
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::testdata::record;

    fn file(runs: Vec<RunRecord>) -> ResultsFile {
        ResultsFile {
            origin: None,
            scenario: "ci".into(),
            runs,
            claims: vec![],
            ..Default::default()
        }
    }

    fn baseline() -> ResultsFile {
        file(vec![
            record("pcss", Backend::CpuModel, 100, 32),
            record("pcss", Backend::CpuModel, 1000, 32),
            record("reference", Backend::CpuNative, 100, 32),
            record("pcss", Backend::Wgpu, 100, 32),
        ])
    }

    fn run(old: &ResultsFile, new: &ResultsFile) -> Comparison {
        compare(
            (Path::new("base.json"), old),
            (Path::new("cur.json"), new),
            &Options::default(),
        )
        .unwrap()
    }

    /// The comparison of the baseline, its first run's counter `name` set to `before`, with the
    /// same results but `after`.
    fn counter_change(name: &str, before: f64, after: f64) -> Comparison {
        let mut b = baseline();
        b.runs[0].counters.set(name, before);
        let mut cur = b.clone();
        cur.runs[0].counters.set(name, after);
        run(&b, &cur)
    }

    #[test]
    fn unchanged_results_pass() {
        let b = baseline();
        let c = run(&b, &b);
        assert!(!c.regressed(), "{}", c.render());
        assert!(c.changes.is_empty() && c.runs.is_empty());
        // The wgpu run contributes no figure; the others all of theirs.
        let expect: usize = b.runs.iter().map(|r| deterministic_figures(r).len()).sum();
        assert_eq!(c.figures_compared, expect);
        assert_eq!(deterministic_figures(&b.runs[3]).len(), 0);
        // The verdict is the last line (`compare` prints it after the headline).
        let verdict = c.render().lines().last().map(str::to_string);
        assert!(
            verdict.is_some_and(|l| l.starts_with("PASS")),
            "{}",
            c.render()
        );
    }

    #[test]
    fn files_of_different_scenarios_say_so_in_the_first_line() {
        let b = baseline();
        let mut cur = baseline();
        cur.scenario = "quick".into();
        let c = run(&b, &cur);
        let text = c.render();
        let first = text.lines().next().unwrap();
        assert!(
            first.contains("different scenarios")
                && first.contains("'ci'")
                && first.contains("'quick'"),
            "{text}"
        );
        // The same scenario: no such line.
        assert!(!run(&b, &b).render().contains("different scenarios"));
    }

    #[test]
    fn a_counter_up_five_percent_fails_naming_it() {
        let b = baseline();
        let mut cur = baseline();
        let fill = cur.runs[1].counters.get("fill").unwrap();
        cur.runs[1].counters.set("fill", fill * 1.05);
        let c = run(&b, &cur);
        assert!(c.regressed());
        assert_eq!(c.changes.len(), 1, "{}", c.render());
        let ch = &c.changes[0];
        assert_eq!(ch.verdict, Verdict::Regression);
        assert_eq!(ch.figure, "counters.fill");
        assert_eq!(ch.case, b.runs[1].case_id());
        assert!((ch.pct() - 5.0).abs() < 1e-9);
        let text = c.render();
        assert!(
            text.contains("REGRESSION") && text.contains("counters.fill"),
            "{text}"
        );
        assert!(text.contains("+5.00%") && text.contains("FAIL"), "{text}");
    }

    #[test]
    fn small_worsening_within_threshold_passes_but_is_listed() {
        let b = baseline();
        let mut cur = baseline();
        let m = cur.runs[0].model_ms.unwrap();
        cur.runs[0].model_ms = Some(m * 1.01);
        let c = run(&b, &cur);
        assert!(!c.regressed());
        assert_eq!(c.changes[0].verdict, Verdict::Worse);
        assert_eq!(c.changes[0].figure, "model_ms");
    }

    #[test]
    fn a_missing_run_fails() {
        let b = baseline();
        let mut cur = baseline();
        let gone = cur.runs.remove(3);
        let c = run(&b, &cur);
        assert!(c.regressed());
        assert_eq!(c.runs, vec![(gone.case_id(), RunStatus::Missing)]);
        assert!(c.render().contains("MISSING"));
    }

    #[test]
    fn a_newly_failing_run_fails_and_a_fixed_one_passes() {
        let b = baseline();
        let mut cur = baseline();
        cur.runs[3].failure = Some("device lost".into());
        let c = run(&b, &cur);
        assert!(c.regressed());
        assert!(c.render().contains("device lost"));
        // The other way round, the run is listed as fixed and the gate passes.
        let c = run(&cur, &b);
        assert!(!c.regressed());
        assert_eq!(c.runs, vec![(b.runs[3].case_id(), RunStatus::Fixed)]);
    }

    #[test]
    fn improvements_pass_and_are_listed_as_better() {
        let b = baseline();
        let mut cur = baseline();
        cur.runs[0].counters.set("mem_model.read_bytes", 1.0);
        let e = cur.runs[2].error.as_mut().unwrap();
        e.mae_shadow = e.mae_shadow.map(|v| v / 2.0);
        cur.runs[0].phases[1].model_ms = Some(0.1);
        let c = run(&b, &cur);
        assert!(!c.regressed(), "{}", c.render());
        let moved: Vec<(&str, Verdict)> = c
            .changes
            .iter()
            .map(|c| (c.figure.as_str(), c.verdict))
            .collect();
        assert_eq!(moved.len(), 3, "{moved:?}");
        assert!(moved.iter().all(|m| m.1 == Verdict::Better), "{moved:?}");
        for f in [
            "counters.mem_model.read_bytes",
            "error.mae_shadow",
            "phase.soft.model_ms",
        ] {
            assert!(moved.iter().any(|m| m.0 == f), "{f}: {moved:?}");
        }
        assert!(c.render().contains("better"));
    }

    #[test]
    fn times_that_are_not_deterministic_are_ignored() {
        let b = baseline();
        let mut cur = baseline();
        for r in &mut cur.runs {
            r.wall_ms *= 3.0;
            r.gpu_ms = Some(100.0);
            r.phases[0].wall_ms *= 3.0;
        }
        // wgpu counters are adapter-dependent: not compared.
        cur.runs[3].counters.set("fill", 1e9);
        // cpu-native has no modelled time to compare.
        cur.runs[2].model_ms = Some(1e9);
        let c = run(&b, &cur);
        assert!(!c.regressed(), "{}", c.render());
        assert!(c.changes.is_empty(), "{}", c.render());
    }

    #[test]
    fn rates_of_good_outcomes_worsen_downwards() {
        let c = counter_change("simd_utilization", 0.8, 0.7);
        assert!(c.regressed());
        assert_eq!(c.changes[0].figure, "counters.simd_utilization");
        // The name the model writes is in the glossary, as a rate of good outcomes.
        assert!(crate::counters::find("simd_utilization").is_some());
        // Its parts (active_lanes / vector_ops × 16) worsened with it: vector_ops rose.
        let mut b = baseline();
        let (lanes, ops) = (800.0, 100.0);
        b.runs[0].counters.set("active_lanes", lanes);
        b.runs[0].counters.set("vector_ops", ops);
        crate::counters::derive(&mut b.runs[0].counters);
        let mut cur = b.clone();
        cur.runs[0].counters.set("vector_ops", ops * 1.2);
        crate::counters::derive(&mut cur.runs[0].counters);
        let c = run(&b, &cur);
        let util = c
            .changes
            .iter()
            .find(|c| c.figure == "counters.simd_utilization")
            .unwrap();
        assert_eq!(util.verdict, Verdict::Regression, "{}", c.render());
    }

    #[test]
    fn cache_hits_worsen_downwards_and_misses_upwards() {
        for (name, before, after, regressed) in [
            ("cache.l1_hits", 1000.0, 900.0, true),
            ("cache.l1_hits", 1000.0, 1100.0, false),
            ("cache.l2_misses", 100.0, 110.0, true),
            ("cache.l2_misses", 100.0, 90.0, false),
        ] {
            let c = counter_change(name, before, after);
            assert_eq!(c.regressed(), regressed, "{name}: {}", c.render());
            assert_eq!(c.changes.len(), 1, "{}", c.render());
        }
    }

    #[test]
    fn a_derived_ratio_is_judged_with_its_parts() {
        let b = baseline();
        let (fill, overdraw) = (
            b.runs[1].counters.get("fill").unwrap(),
            b.runs[1].counters.get("overdraw").unwrap(),
        );
        assert!(b.runs[1].counters.get("overdraw_ratio").is_some());
        // Fill falls by a fifth, overdraw stays: the ratio rises 25%, but nothing got worse.
        let mut cur = b.clone();
        cur.runs[1].counters.set("fill", fill * 0.8);
        crate::counters::derive(&mut cur.runs[1].counters);
        let c = run(&b, &cur);
        assert!(!c.regressed(), "{}", c.render());
        let ratio = c
            .changes
            .iter()
            .find(|c| c.figure == "counters.overdraw_ratio")
            .unwrap();
        assert_eq!(ratio.verdict, Verdict::Worse);
        assert!((ratio.pct() - 25.0).abs() < 1e-6, "{}", ratio.pct());
        let text = c.render();
        assert!(text.contains("judged with its parts"), "{text}");
        // Overdraw rises a quarter: the ratio's regression stands beside its part's.
        let mut cur = b.clone();
        cur.runs[1].counters.set("overdraw", overdraw * 1.25);
        crate::counters::derive(&mut cur.runs[1].counters);
        let c = run(&b, &cur);
        let gated: Vec<&str> = c
            .changes
            .iter()
            .filter(|c| c.verdict == Verdict::Regression)
            .map(|c| c.figure.as_str())
            .collect();
        assert_eq!(
            gated,
            ["counters.overdraw", "counters.overdraw_ratio"],
            "{}",
            c.render()
        );
    }

    #[test]
    fn a_figure_outside_the_glossary_is_listed_not_judged() {
        // The name sounds like a rate of good outcomes; nothing is guessed from it.
        let c = counter_change("texture_hit_rate", 0.9, 0.1);
        assert!(!c.regressed(), "{}", c.render());
        assert!(c.changes.is_empty());
        assert_eq!(c.unjudged.get("counters.texture_hit_rate"), Some(&1));
        assert!(
            c.render()
                .contains("counters.texture_hit_rate is not in the glossary"),
            "{}",
            c.render()
        );
    }

    #[test]
    fn an_increase_from_zero_is_a_regression() {
        let c = counter_change("atomics", 0.0, 3.0);
        assert!(c.regressed());
        assert!(c.render().contains("+inf%"), "{}", c.render());
    }

    /// `r` measured with wall-time samples `wall` (and GPU samples `gpu`).
    fn measured(mut r: RunRecord, wall: Vec<f64>, gpu: Option<Vec<f64>>) -> RunRecord {
        use crate::harness::measure::{Measure, Measured, Spread};
        r.measured = Some(Measured {
            protocol: Measure::default(),
            iterations: wall.len() as u32,
            warmup_runs: 0,
            wall_ms: Spread::of(wall).unwrap(),
            gpu_ms: gpu.map(|g| Spread::of(g).unwrap()),
            phases: vec![],
            identical: true,
            warnings: vec![],
        });
        r
    }

    /// Ten noisy samples around `ms` (a fixed pattern of ±3%), shifted by `phase` steps.
    fn samples(ms: f64, phase: usize) -> Vec<f64> {
        let noise = [
            0.0, 0.02, -0.01, 0.03, -0.03, 0.01, -0.02, 0.025, -0.015, 0.005,
        ];
        (0..10)
            .map(|i| ms * (1.0 + noise[(i + phase) % 10]))
            .collect()
    }

    #[test]
    fn a_measured_figure_twice_as_slow_is_flagged_alone_and_gates_only_when_asked() {
        let mk = |slow: f64| {
            file(
                (0..8)
                    .map(|i| {
                        let r = record("pcss", Backend::Wgpu, 100 * (i + 1), 32);
                        let f = if i == 3 { slow } else { 1.0 };
                        measured(
                            r,
                            samples(10.0 * f, i as usize),
                            Some(samples(4.0 * f, i as usize + 3)),
                        )
                    })
                    .collect(),
            )
        };
        let (b, same, slower) = (mk(1.0), mk(1.0), mk(2.0));
        let c = run(&b, &same);
        assert_eq!(c.measured.tests.len(), 16);
        assert_eq!(c.measured.regressions(), 0, "{}", c.render());
        let c = run(&b, &slower);
        let flagged: Vec<_> = c
            .measured
            .tests
            .iter()
            .filter(|t| t.flagged(c.measured.q))
            .collect();
        assert_eq!(flagged.len(), 2, "{}", c.render());
        for t in &flagged {
            assert_eq!(t.case, b.runs[3].case_id());
            assert!((t.ratio() - 2.0).abs() < 0.1 && t.q < 0.05, "{t:?}");
        }
        let text = c.render();
        assert!(
            text.contains("SLOWER") && text.contains("without --gate measured"),
            "{text}"
        );
        // Reported, not gated, unless asked.
        assert!(!c.regressed(), "{text}");
        let gate = Options {
            gate_measured: true,
            ..Options::default()
        };
        let c = compare((Path::new("b"), &b), (Path::new("c"), &slower), &gate).unwrap();
        assert!(c.regressed());
        // A figure's own minimum effect above the change: not flagged.
        let mut lenient = gate.clone();
        lenient
            .set_per_figure(&["wall_ms=150".into(), "gpu_ms=150".into()])
            .unwrap();
        let c = compare((Path::new("b"), &b), (Path::new("c"), &slower), &lenient).unwrap();
        assert!(!c.regressed(), "{}", c.render());
    }

    /// A sweep of 60 runs (1–300 ms) measured in two sittings: each run's whole set of samples
    /// moved by its sitting (log-normal, 4% plus a larger share for short runs, and three runs
    /// 30% off), the samples within a sitting 1% apart, as on a shared two-core machine.
    fn sittings(doubled: &[usize]) -> (ResultsFile, ResultsFile) {
        // A fixed sequence of standard normal deviates (Box–Muller over a linear congruential
        // generator), so the test is deterministic.
        let mut state: u64 = 0x2545_f491_4f6c_dd1d;
        let mut uniform = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut normal = move || {
            let (u, v) = (uniform(), uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        let (mut old, mut new) = (vec![], vec![]);
        for i in 0..60usize {
            let ms = 300f64.powf(i as f64 / 59.0);
            let sigma = (0.04f64.powi(2) + 0.01 / ms).sqrt();
            let shift = if i % 20 == 7 { 0.3 } else { sigma * normal() };
            let work = if doubled.contains(&i) { 2.0 } else { 1.0 };
            let take = |centre: f64, normal: &mut dyn FnMut() -> f64| -> Vec<f64> {
                (0..10).map(|_| centre * (1.0 + 0.01 * normal())).collect()
            };
            let r = record("pcss", Backend::CpuNative, 100 * (i as u32 + 1), 32);
            old.push(measured(r.clone(), take(ms, &mut normal), None));
            new.push(measured(
                r,
                take(ms * work * shift.exp(), &mut normal),
                None,
            ));
        }
        (file(old), file(new))
    }

    #[test]
    fn the_noise_between_sittings_keeps_an_unchanged_sweep_quiet_and_finds_a_doubled_run() {
        let (b, same) = sittings(&[]);
        let c = run(&b, &same);
        // The samples alone see the sittings' shifts as changes.
        let on_samples = c
            .measured
            .tests
            .iter()
            .filter(|t| {
                t.p_samples * c.measured.tests.len() as f64 <= 0.05
                    && (t.ratio() - 1.0).abs() >= 0.1
            })
            .count();
        assert!(on_samples >= 3, "{on_samples}: {}", c.render());
        let flagged = |c: &Comparison| -> Vec<String> {
            c.measured
                .tests
                .iter()
                .filter(|t| t.flagged(c.measured.q))
                .map(|t| t.case.clone())
                .collect()
        };
        assert!(flagged(&c).is_empty(), "{}", c.render());
        let noise = c.measured.noise["wall_ms"];
        assert!(
            (0.02..0.08).contains(&noise.sigma0),
            "{noise:?} against 4% drawn"
        );
        // Two runs of 50 ms and more made twice as slow: flagged, and nothing else.
        let (b, slower) = sittings(&[45, 52]);
        let c = run(&b, &slower);
        let expect = vec![b.runs[45].case_id(), b.runs[52].case_id()];
        assert_eq!(flagged(&c), expect, "{}", c.render());
        assert!(c.render().contains("noise between sittings of wall_ms"));
    }

    #[test]
    fn per_figure_thresholds_apply_by_glossary_name_and_are_checked() {
        let mut o = Options::default();
        o.set_per_figure(&["fill=10".into()]).unwrap();
        let b = baseline();
        let mut cur = baseline();
        let fill = cur.runs[1].counters.get("fill").unwrap();
        cur.runs[1].counters.set("fill", fill * 1.05);
        let c = compare((Path::new("b"), &b), (Path::new("c"), &cur), &o).unwrap();
        assert!(!c.regressed(), "{}", c.render());
        assert_eq!(c.changes[0].verdict, Verdict::Worse);
        for bad in ["fil=3", "fill", "fill=-1", "fill=x"] {
            let e = Options::default()
                .set_per_figure(&[bad.into()])
                .unwrap_err()
                .to_string();
            assert!(e.contains("--threshold-for") && e.contains(bad), "{e}");
        }
    }

    #[test]
    fn a_baseline_with_no_runs_is_refused() {
        let e = compare(
            (Path::new("base.json"), &file(vec![])),
            (Path::new("cur.json"), &baseline()),
            &Options::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("base.json: $.runs: ") && e.contains("nothing would be compared"),
            "{e}"
        );
    }

    #[test]
    fn duplicate_runs_and_bad_thresholds_are_input_errors() {
        let mut dup = baseline();
        dup.runs.push(dup.runs[0].clone());
        let e = compare(
            (Path::new("base.json"), &baseline()),
            (Path::new("cur.json"), &dup),
            &Options::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("cur.json") && e.contains("$.runs[4]"), "{e}");
        let e = check_threshold(-1.0).unwrap_err().to_string();
        assert!(e.contains("--threshold") && e.contains("-1"), "{e}");
    }
}
