//! Incremental results: after every run, `results.json` and `results.csv` are rewritten
//! atomically (temporary file + rename), so a sweep cut short keeps every finished run and never
//! leaves a half-written file.

use std::path::{Path, PathBuf};

use crate::error::Result;
use crate::frame::Frame;
use crate::record::RunRecord;
use crate::scenario::claims::Claim;
use crate::visibility::{write_atomic, RgbBuffer, VisibilityBuffer};

pub struct ResultsWriter {
    out: PathBuf,
    file: ResultsFile,
    /// Runs kept from an interrupted sweep of the same scenario and build, not yet reached in
    /// this one's plan: written after the new runs until their turn comes ([`Self::take_kept`]),
    /// so a second interruption loses none of them.
    kept: Vec<RunRecord>,
    /// ꟻLIP's viewing condition for each run's `flip.png` (`reference.flip_pixels_per_degree`).
    pixels_per_degree: f32,
}

/// What a sweep's results were made of: the scenario (a digest of it as run, with the resolved
/// machine and the wgpu counter mode) and the build ([`crate::build::id`]). A sweep resumes
/// into a folder only when both are its own.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Origin {
    pub scenario_digest: String,
    pub build: String,
}

/// The file `results.json` holds: the scenario name and its runs.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ResultsFile {
    pub scenario: String,
    /// Written by `run`; absent in merged files and older results (which then cannot be
    /// resumed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin: Option<Origin>,
    pub runs: Vec<RunRecord>,
    /// The paper claims the scenario states, evaluated by the report.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub claims: Vec<Claim>,
    /// The command line's overrides of the scenario (`run --set` / `--sweep`) as `PATH=VALUE`;
    /// empty when the file ran as written.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub overrides: Vec<String>,
    /// The scenario as it ran (its file with the overrides applied), as JSON; absent in files
    /// of older versions. `compare` names the settings that differ between two files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub config: Option<serde_json::Value>,
}

impl ResultsFile {
    /// Refuses a file in which one run (one [`RunRecord::case_id`]) appears more than once,
    /// naming the second one: which of the two counts is undecidable, so neither `report` nor
    /// `compare` nor `merge` picks one. (A run naming an execution that does not exist does not
    /// read: [`crate::backend::Backend`].)
    pub fn check_runs(&self) -> std::result::Result<(), crate::error::InputError> {
        let mut seen = std::collections::HashSet::new();
        for (i, r) in self.runs.iter().enumerate() {
            if !seen.insert(r.case_id()) {
                return Err(crate::error::InputError::new(
                    format!("$.runs[{i}]"),
                    format!("run '{}' appears more than once", r.case_id()),
                ));
            }
        }
        Ok(())
    }

    /// The file with the counters of records written by older versions under their current
    /// names ([`crate::counters::current_name`]) and the derived figures computed again
    /// ([`crate::counters::derive`]), so old and new results chart and compare alike.
    pub fn upgraded(mut self) -> ResultsFile {
        for r in &mut self.runs {
            let (notes, warnings) = std::mem::take(&mut r.warnings)
                .into_iter()
                .partition::<Vec<String>, _>(|w| crate::record::is_note(w));
            r.notes.extend(notes);
            r.warnings = warnings;
            crate::counters::upgrade(r.backend, &mut r.counters);
            crate::counters::derive(&mut r.counters);
            for p in &mut r.phases {
                crate::counters::upgrade(r.backend, &mut p.counters);
                crate::counters::derive(&mut p.counters);
            }
        }
        self
    }
}

impl ResultsWriter {
    /// A writer of the results of scenario `loaded` into `out`, from `origin` (what a resumed
    /// sweep must match), keeping the runs `kept` from the sweep it resumes.
    pub fn new(
        out: &Path,
        loaded: &crate::scenario::Loaded,
        origin: Option<Origin>,
        kept: Vec<RunRecord>,
    ) -> ResultsWriter {
        ResultsWriter {
            out: out.to_path_buf(),
            file: ResultsFile {
                scenario: loaded.name(),
                origin,
                runs: Vec::new(),
                claims: loaded.scenario.claims.clone(),
                overrides: loaded.overrides.clone(),
                config: serde_json::to_value(&loaded.scenario).ok(),
            },
            kept,
            pixels_per_degree: loaded.scenario.reference.flip_pixels_per_degree(),
        }
    }

    /// Adds a finished run: writes its images under `images/<case>/` and rewrites the results.
    pub fn push(
        &mut self,
        record: RunRecord,
        visibility: Option<&VisibilityBuffer>,
        rgb: Option<&RgbBuffer>,
        reference: Option<&VisibilityBuffer>,
        frame: Option<&Frame>,
    ) -> Result<()> {
        if let Some(frame) = frame {
            let dir = self.out.join("images").join(record.case_id());
            super::write_frame_files(
                &dir,
                &record,
                visibility,
                rgb,
                reference,
                frame,
                self.pixels_per_degree,
            )?;
        }
        self.file.runs.push(record);
        write_results(&self.out, &self.current())
    }

    /// Moves the kept run `case_id` (with its images, already in place) to its turn in the
    /// results; whether there was one.
    pub fn take_kept(&mut self, case_id: &str) -> bool {
        match self.kept.iter().position(|r| r.case_id() == case_id) {
            Some(i) => {
                let r = self.kept.remove(i);
                self.file.runs.push(r);
                true
            }
            None => false,
        }
    }

    /// How many kept runs have not had their turn yet.
    pub fn kept_left(&self) -> usize {
        self.kept.len()
    }

    /// The results so far: the runs in plan order, then the kept runs not reached yet.
    fn current(&self) -> ResultsFile {
        let mut f = self.file.clone();
        f.runs.extend(self.kept.iter().cloned());
        f
    }

    /// The results (writes them once more, so a sweep that only took kept runs leaves them in
    /// plan order).
    pub fn finish(self) -> Result<ResultsFile> {
        let f = self.current();
        write_results(&self.out, &f)?;
        Ok(f)
    }
}

/// The finished runs of an earlier sweep in `out` to keep (`results.json`), when it was of the
/// same scenario and build (`origin`); empty when there is none or `fresh`. Failed runs are
/// kept unless `retry_failed`. Results of another scenario or build, or without an origin,
/// are an input error naming the file and saying how to start afresh.
pub fn resumable(
    out: &Path,
    origin: &Origin,
    fresh: bool,
    retry_failed: bool,
) -> std::result::Result<Vec<RunRecord>, crate::error::InputError> {
    let path = out.join("results.json");
    if fresh || !path.exists() {
        return Ok(vec![]);
    }
    let refuse = |why: String| {
        crate::error::InputError::file(
            &path,
            format!(
                "{why}; pass --fresh to replace them, or choose another --out (a sweep resumes \
                 only the results of its own scenario and build)"
            ),
        )
    };
    let text = std::fs::read(&path).map_err(|e| refuse(format!("cannot be read: {e}")))?;
    // A run naming an unknown execution does not read: its path and value are in the message.
    let file: ResultsFile = crate::util::json::parse(&String::from_utf8_lossy(&text), &path)
        .map_err(|e| {
            let at = e.field.map(|f| format!("{f}: ")).unwrap_or_default();
            refuse(format!(
                "holds results that cannot be read ({at}{})",
                e.message
            ))
        })?;
    let mismatch = match &file.origin {
        None => Some(format!(
            "holds results of scenario '{}' that do not say what they were made of",
            file.scenario
        )),
        Some(o) if o.scenario_digest != origin.scenario_digest => Some(format!(
            "holds results of another scenario ('{}', digest {}; this one's is {})",
            file.scenario, o.scenario_digest, origin.scenario_digest
        )),
        Some(o) if o.build != origin.build => Some(format!(
            "holds results of scenario '{}' made by another build ({}; this is {})",
            file.scenario, o.build, origin.build
        )),
        Some(_) => None,
    };
    if let Some(why) = mismatch {
        return Err(refuse(why));
    }
    file.check_runs().map_err(|e| e.in_file(&path))?;
    Ok(file
        .upgraded()
        .runs
        .into_iter()
        .filter(|r| r.failure.is_none() || !retry_failed)
        .collect())
}

/// Writes `out/results.json`, `out/results.csv` and `out/phases.csv`, each atomically.
pub fn write_results(out: &Path, file: &ResultsFile) -> Result<()> {
    let json = serde_json::to_vec_pretty(file).expect("records serialize");
    write_atomic(&out.join("results.json"), &json)?;
    write_atomic(&out.join("results.csv"), csv(&file.runs).as_bytes())?;
    write_atomic(&out.join("phases.csv"), phases_csv(&file.runs).as_bytes())
}

/// A CSV field: quoted (inner quotes doubled, RFC 4180) when it holds a comma, quote or line
/// break.
fn field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Per-phase times in tidy (long) form, one row per run, phase and time kind: `case_id,
/// algorithm, variant, backend, scene, phase, time (wall_ms | model_ms | gpu_ms), ms`, so pandas and R
/// can group them; measured times add the 95% interval of their median (`ci_lo`, `ci_hi`) and
/// their samples (space-separated), empty for modelled ones.
pub fn phases_csv(records: &[RunRecord]) -> String {
    let mut s =
        String::from("case_id,algorithm,variant,backend,scene,phase,time,ms,ci_lo,ci_hi,samples\n");
    for r in records {
        for (i, p) in r.phases.iter().enumerate() {
            let spread = r
                .measured
                .as_ref()
                .and_then(|m| m.phases.get(i))
                .filter(|s| s.name == p.name);
            for (kind, v, sp) in [
                ("wall_ms", Some(p.wall_ms), spread.map(|s| &s.wall_ms)),
                ("model_ms", p.model_ms, None),
                ("gpu_ms", p.gpu_ms, spread.and_then(|s| s.gpu_ms.as_ref())),
            ] {
                if let Some(v) = v {
                    let [lo, hi, samples] = spread_fields(sp);
                    s.push_str(&format!(
                        "{},{},{},{},{},{},{kind},{v},{lo},{hi},{samples}\n",
                        field(&r.case_id()),
                        field(&r.algorithm),
                        field(r.variant.as_deref().unwrap_or_default()),
                        field(r.backend.name()),
                        field(&r.scene),
                        field(&p.name)
                    ));
                }
            }
        }
    }
    s
}

/// A measured figure's interval bounds and samples (space-separated) as CSV fields; empty
/// without a measurement.
fn spread_fields(s: Option<&crate::harness::measure::Spread>) -> [String; 3] {
    match s {
        Some(s) => [
            s.ci[0].to_string(),
            s.ci[1].to_string(),
            s.samples
                .iter()
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(" "),
        ],
        None => Default::default(),
    }
}

/// The counters `results.csv` has a column for: one kind of figure per column (modelled and
/// estimated memory traffic apart, [`crate::counters`]).
const CSV_COUNTERS: [&str; 7] = [
    "fill",
    "overdraw",
    "overdraw_ratio",
    "mem_model.read_bytes",
    "mem_model.write_bytes",
    "mem_est.read_bytes",
    "mem_est.write_bytes",
];

/// One row per run with the headline columns — the case id, the run's image folder (relative to
/// the results, empty for a failed run) and its warnings included; every counter stays in
/// results.json.
pub fn csv(records: &[RunRecord]) -> String {
    let mut s = String::from(
        "case_id,algorithm,variant,backend,scene,light,triangles,light_size,map_resolution,tile_size,image_w,image_h,occluder_height,occluder_offset,cores,wall_ms,model_ms,gpu_ms,\
         wall_ms_ci_lo,wall_ms_ci_hi,gpu_ms_ci_lo,gpu_ms_ci_hi,cold_wall_ms,cold_gpu_ms,samples,wall_ms_samples,gpu_ms_samples",
    );
    for c in CSV_COUNTERS {
        s.push(',');
        s.push_str(c);
    }
    s.push_str(
        ",mae,rmse,max,mae_shadow,frac_over_0_1,mae_shadow_receivers,grazing_pixels,mae_shadow_non_grazing,mae_penumbra,umbra_error,lit_error,flip,ssim,images,warnings,measure_warnings,failure\n",
    );
    let opt = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_default();
    for r in records {
        let p = &r.params;
        let mut row = vec![
            field(&r.case_id()),
            r.algorithm.clone(),
            field(r.variant.as_deref().unwrap_or_default()),
            r.backend.name().to_string(),
            r.scene.clone(),
            r.light.clone(),
            p.triangles.to_string(),
            crate::record::fmt_light_size(p.light_size),
            p.map_resolution.to_string(),
            p.tile_size.to_string(),
            p.image[0].to_string(),
            p.image[1].to_string(),
            opt(p.occluder_height.map(f64::from)),
            opt(p.occluder_offset.map(f64::from)),
            opt(p.cores.map(f64::from)),
            r.wall_ms.to_string(),
            opt(r.model_ms),
            opt(r.gpu_ms),
        ];
        let m = r.measured.as_ref();
        let [wall_lo, wall_hi, wall_samples] = spread_fields(m.map(|m| &m.wall_ms));
        let [gpu_lo, gpu_hi, gpu_samples] = spread_fields(m.and_then(|m| m.gpu_ms.as_ref()));
        row.extend([
            wall_lo,
            wall_hi,
            gpu_lo,
            gpu_hi,
            opt(r.cold_wall_ms),
            opt(r.cold_gpu_ms),
            m.map(|m| m.iterations.to_string()).unwrap_or_default(),
            wall_samples,
            gpu_samples,
        ]);
        row.extend(CSV_COUNTERS.iter().map(|c| opt(r.counters.get(c))));
        let e = r.error.as_ref();
        row.extend([
            opt(e.and_then(|e| e.mae)),
            opt(e.and_then(|e| e.rmse)),
            opt(e.and_then(|e| e.max)),
            opt(e.and_then(|e| e.mae_shadow)),
            opt(e.and_then(|e| e.frac_over_0_1)),
            opt(e.and_then(|e| e.mae_shadow_receivers)),
            e.map(|e| e.grazing_pixels.to_string()).unwrap_or_default(),
            opt(e.and_then(|e| e.mae_shadow_non_grazing)),
            opt(e.and_then(|e| e.mae_penumbra)),
            opt(e.and_then(|e| e.umbra_error)),
            opt(e.and_then(|e| e.lit_error)),
            opt(e.and_then(|e| e.flip)),
            opt(e.and_then(|e| e.ssim)),
            if r.failure.is_none() {
                format!("images/{}", field(&r.case_id()))
            } else {
                String::new()
            },
            field(&r.warnings.join("; ")),
            field(&m.map(|m| m.warnings.join("; ")).unwrap_or_default()),
            r.failure.as_deref().map(field).unwrap_or_default(),
        ]);
        s.push_str(&row.join(","));
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::Backend;
    use crate::report::testdata::record;

    /// Splits CSV text into rows of fields (RFC 4180 quoting), as a CSV reader would.
    fn parse(text: &str) -> Vec<Vec<String>> {
        let mut rows = vec![];
        let mut row = vec![];
        let mut cur = String::new();
        let mut quoted = false;
        let mut chars = text.chars().peekable();
        while let Some(c) = chars.next() {
            match (c, quoted) {
                ('"', true) if chars.peek() == Some(&'"') => {
                    cur.push('"');
                    chars.next();
                }
                ('"', _) => quoted = !quoted,
                (',', false) => row.push(std::mem::take(&mut cur)),
                ('\n', false) => {
                    row.push(std::mem::take(&mut cur));
                    rows.push(std::mem::take(&mut row));
                }
                (c, _) => cur.push(c),
            }
        }
        rows
    }

    #[test]
    fn results_csv_has_the_case_id_image_folder_and_warnings_in_every_row() {
        let mut ok = record("pcss", Backend::CpuModel, 100, 32);
        ok.params.light_size = 0.6;
        ok.variant = Some("raw".into());
        ok.warnings = vec!["light converted, from disc".into(), "two".into()];
        let mut bad = record("dbuffer", Backend::Wgpu, 100, 32);
        bad.failure = Some("no \"adapter\", sorry".into());
        let rows = parse(&csv(&[ok.clone(), bad.clone()]));
        assert_eq!(rows.len(), 3);
        let col = |name: &str| rows[0].iter().position(|c| c == name).unwrap();
        for r in &rows {
            assert_eq!(r.len(), rows[0].len(), "{r:?}");
        }
        assert_eq!(rows[1][col("case_id")], ok.case_id());
        assert_eq!(rows[1][col("algorithm")], "pcss");
        assert_eq!(rows[1][col("variant")], "raw");
        assert_eq!(rows[2][col("variant")], "");
        assert_eq!(rows[1][col("images")], format!("images/{}", ok.case_id()));
        assert_eq!(rows[1][col("warnings")], "light converted, from disc; two");
        // The light size reads the same in the CSV and in the folder name.
        assert_eq!(rows[1][col("light_size")], "0.6");
        assert!(ok.case_id().contains("_l0.6_"), "{}", ok.case_id());
        assert_eq!(rows[2][col("images")], "");
        assert_eq!(rows[2][col("failure")], "no \"adapter\", sorry");
    }

    #[test]
    fn phases_csv_is_long_one_row_per_run_phase_and_time() {
        let r = record("pcss", Backend::CpuModel, 100, 32);
        let rows = parse(&phases_csv(std::slice::from_ref(&r)));
        assert_eq!(
            rows[0],
            [
                "case_id",
                "algorithm",
                "variant",
                "backend",
                "scene",
                "phase",
                "time",
                "ms",
                "ci_lo",
                "ci_hi",
                "samples"
            ]
        );
        // Two phases, each with a wall and a modelled time, no GPU time.
        assert_eq!(rows.len(), 1 + 4);
        let expect: Vec<(String, String, f64)> = r
            .phases
            .iter()
            .flat_map(|p| {
                [
                    (p.name.clone(), "wall_ms".to_string(), p.wall_ms),
                    (p.name.clone(), "model_ms".to_string(), p.model_ms.unwrap()),
                ]
            })
            .collect();
        let got: Vec<(String, String, f64)> = rows[1..]
            .iter()
            .map(|x| (x[5].clone(), x[6].clone(), x[7].parse().unwrap()))
            .collect();
        assert_eq!(got, expect);
        assert!(rows[1..].iter().all(|x| x[0] == r.case_id()));
    }

    #[test]
    fn measured_times_carry_their_interval_and_samples_into_both_tables() {
        use crate::harness::measure::{Measure, Measured, PhaseSpread, Spread};
        let mut r = record("pcss", Backend::Wgpu, 100, 32);
        let wall = Spread::of(vec![3.0, 1.0, 2.0, 5.0, 4.0, 6.0, 7.0]).unwrap();
        r.cold_wall_ms = Some(30.0);
        r.measured = Some(Measured {
            protocol: Measure::default(),
            iterations: 7,
            warmup_runs: 0,
            wall_ms: wall.clone(),
            gpu_ms: None,
            phases: vec![PhaseSpread {
                name: "construct".into(),
                wall_ms: Spread::of(vec![1.0, 1.5]).unwrap(),
                gpu_ms: None,
            }],
            identical: true,
            warnings: vec!["wide interval".into()],
        });
        let rows = parse(&csv(std::slice::from_ref(&r)));
        let col = |name: &str| rows[0].iter().position(|c| c == name).unwrap();
        assert_eq!(rows[1][col("wall_ms_ci_lo")], wall.ci[0].to_string());
        assert_eq!(rows[1][col("wall_ms_ci_hi")], wall.ci[1].to_string());
        assert_eq!(rows[1][col("cold_wall_ms")], "30");
        assert_eq!(rows[1][col("samples")], "7");
        assert_eq!(rows[1][col("wall_ms_samples")], "3 1 2 5 4 6 7");
        assert_eq!(rows[1][col("gpu_ms_samples")], "");
        assert_eq!(rows[1][col("measure_warnings")], "wide interval");
        let rows = parse(&phases_csv(std::slice::from_ref(&r)));
        assert_eq!(
            rows[1][5..],
            ["construct", "wall_ms", "1", "1", "1.5", "1 1.5"]
        );
        // Modelled times have no samples.
        assert_eq!(rows[2][6..], ["model_ms", "0.4", "", "", ""]);
    }
}
