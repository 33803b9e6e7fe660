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
}

/// The file `results.json` holds: the scenario name and its runs.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ResultsFile {
    pub scenario: String,
    pub runs: Vec<RunRecord>,
    /// The paper claims the scenario states, evaluated by the report.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub claims: Vec<Claim>,
}

impl ResultsFile {
    /// Refuses a file in which one run (one [`RunRecord::case_id`]) appears more than once,
    /// naming the second one: which of the two counts is undecidable, so neither `report` nor
    /// `compare` nor `merge` picks one.
    pub fn check_unique_runs(&self) -> std::result::Result<(), crate::error::InputError> {
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
}

impl ResultsWriter {
    pub fn new(out: &Path, scenario: &str, claims: &[Claim]) -> ResultsWriter {
        ResultsWriter {
            out: out.to_path_buf(),
            file: ResultsFile {
                scenario: scenario.to_string(),
                runs: Vec::new(),
                claims: claims.to_vec(),
            },
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
            super::write_frame_files(&dir, &record, visibility, rgb, reference, frame)?;
        }
        self.file.runs.push(record);
        write_results(&self.out, &self.file)
    }

    pub fn into_results(self) -> ResultsFile {
        self.file
    }
}

/// Writes `out/results.json` and `out/results.csv`, each atomically.
pub fn write_results(out: &Path, file: &ResultsFile) -> Result<()> {
    let json = serde_json::to_vec_pretty(file).expect("records serialize");
    write_atomic(&out.join("results.json"), &json)?;
    write_atomic(&out.join("results.csv"), csv(&file.runs).as_bytes())
}

const CSV_COUNTERS: [&str; 4] = ["fill", "overdraw", "mem_read_bytes", "mem_write_bytes"];

/// One row per run with the headline columns; every counter stays in results.json.
pub fn csv(records: &[RunRecord]) -> String {
    let mut s = String::from(
        "algorithm,backend,scene,light,triangles,light_size,map_resolution,tile_size,image_w,image_h,occluder_height,occluder_offset,cores,wall_ms,model_ms,gpu_ms",
    );
    for c in CSV_COUNTERS {
        s.push(',');
        s.push_str(c);
    }
    s.push_str(",mae,rmse,max,mae_shadow,frac_over_0_1,mae_shadow_receivers,failure\n");
    let opt = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_default();
    for r in records {
        let p = &r.params;
        let mut row = vec![
            r.algorithm.clone(),
            r.backend.clone(),
            r.scene.clone(),
            r.light.clone(),
            p.triangles.to_string(),
            p.light_size.to_string(),
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
        row.extend(CSV_COUNTERS.iter().map(|c| opt(r.counters.get(c))));
        let e = r.error.as_ref();
        row.extend([
            opt(e.map(|e| e.mae)),
            opt(e.map(|e| e.rmse)),
            opt(e.map(|e| e.max)),
            opt(e.map(|e| e.mae_shadow)),
            opt(e.map(|e| e.frac_over_0_1)),
            opt(e.and_then(|e| e.mae_shadow_receivers)),
            r.failure
                .as_ref()
                .map(|f| format!("\"{}\"", f.replace('"', "'")))
                .unwrap_or_default(),
        ]);
        s.push_str(&row.join(","));
        s.push('\n');
    }
    s
}
