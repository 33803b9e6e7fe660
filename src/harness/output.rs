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
    pub fn read(path: &Path) -> Result<ResultsFile> {
        let text = std::fs::read_to_string(path).map_err(|e| crate::error::Error::io(path, e))?;
        let file: ResultsFile = serde_json::from_str(&text).map_err(|e| {
            crate::error::Error::from(crate::error::InputError::file(
                path,
                format!("not a results file: {e}"),
            ))
        })?;
        Ok(file.upgraded())
    }

    /// The file with the counters of records written by older versions under their current
    /// names ([`crate::counters::current_name`]) and the derived figures computed again
    /// ([`crate::counters::derive`]), so old and new results chart and compare alike.
    pub fn upgraded(mut self) -> ResultsFile {
        for r in &mut self.runs {
            crate::counters::upgrade(&r.backend, &mut r.counters);
            crate::counters::derive(&mut r.counters);
            for p in &mut r.phases {
                crate::counters::upgrade(&r.backend, &mut p.counters);
                crate::counters::derive(&mut p.counters);
            }
        }
        self
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

/// One row per run with the headline columns; every counter stays in results.json.
pub fn csv(records: &[RunRecord]) -> String {
    let mut s = String::from(
        "algorithm,backend,scene,light,triangles,light_size,map_resolution,tile_size,image_w,image_h,occluder_height,occluder_offset,cores,wall_ms,model_ms,gpu_ms",
    );
    for c in CSV_COUNTERS {
        s.push(',');
        s.push_str(c);
    }
    s.push_str(",mae,rmse,max,mae_shadow,frac_over_0_1,failure\n");
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
        row.extend((0..5).map(|i| opt(e.and_then(|e| e.named()[i].1))));
        row.extend([r
            .failure
            .as_ref()
            .map(|f| format!("\"{}\"", f.replace('"', "'")))
            .unwrap_or_default()]);
        s.push_str(&row.join(","));
        s.push('\n');
    }
    s
}
