//! The history database: one SQLite file (rusqlite, SQLite compiled in).
//!
//! # Schema, version 1
//!
//! The file is marked as a shadowbench history by `PRAGMA application_id` = `0x53424853`
//! ("SBHS") and carries its schema version in `PRAGMA user_version` (and in `meta`).
//!
//! ```sql
//! meta       (key TEXT PRIMARY KEY, value TEXT)          -- format, schema_version, created_by
//! commits    (id, sha TEXT UNIQUE, date TEXT, subject TEXT)
//!             -- date: the commit's date in UTC, 'YYYY-MM-DDTHH:MM:SSZ'; commits are ordered
//!             -- by date, then by when they were first recorded
//! machines   (id, fingerprint TEXT UNIQUE, description TEXT)   -- description: JSON
//! recordings (id, commit_id, branch TEXT, source TEXT, digest TEXT, recorded_at TEXT,
//!             runs INTEGER, points INTEGER, UNIQUE (commit_id, digest))
//! series     (id, scenario, case_id, algorithm, execution, figure, machine_id,
//!             UNIQUE (scenario, case_id, figure, machine_id))
//! points     (series_id, commit_id, recording_id, value REAL, lower REAL, upper REAL,
//!             samples TEXT,  -- JSON array of numbers, or NULL
//!             PRIMARY KEY (series_id, commit_id))
//! ```
//!
//! A series is one figure of one run (scenario, case id) on one machine ([`super::provenance`]:
//! the host and, per execution, the modelled machine or the GPU adapter and driver); a point is
//! its value at one commit. Recording the same results again (same commit, same content, same
//! host) changes nothing; results recorded again for a commit replace that commit's points of
//! the same series.
//!
//! Several processes may record at once (CI shards): the file is in WAL mode, every writer
//! waits up to [`BUSY_TIMEOUT`] for the lock, and each recording is one transaction, so a
//! reader sees a recording whole or not at all.
//!
//! A file that is not an SQLite database, is damaged, belongs to another application or was
//! written by a newer schema is an input error naming it (exit 2).

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::time::Duration;

use rusqlite::{params, Connection, ErrorCode, OptionalExtension, TransactionBehavior};
use serde_json::Value;

use super::figures::{self, Point};
use super::provenance::{self, Commit};
use crate::backend::Backend;
use crate::error::{Error, InputError, Result};
use crate::record::RunRecord;

/// `PRAGMA application_id` of a history database: "SBHS".
pub const APPLICATION_ID: i64 = 0x5342_4853;
/// The schema this version writes and reads.
pub const SCHEMA_VERSION: i64 = 1;
/// How long a writer waits for another writer's lock.
pub const BUSY_TIMEOUT: Duration = Duration::from_secs(60);

const SCHEMA: &str = "
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE commits (
    id INTEGER PRIMARY KEY,
    sha TEXT NOT NULL UNIQUE,
    date TEXT NOT NULL,
    subject TEXT NOT NULL DEFAULT ''
);
CREATE TABLE machines (
    id INTEGER PRIMARY KEY,
    fingerprint TEXT NOT NULL UNIQUE,
    description TEXT NOT NULL
);
CREATE TABLE recordings (
    id INTEGER PRIMARY KEY,
    commit_id INTEGER NOT NULL REFERENCES commits(id),
    branch TEXT NOT NULL,
    source TEXT NOT NULL,
    digest TEXT NOT NULL,
    recorded_at TEXT NOT NULL,
    runs INTEGER NOT NULL,
    points INTEGER NOT NULL,
    UNIQUE (commit_id, digest)
);
CREATE TABLE series (
    id INTEGER PRIMARY KEY,
    scenario TEXT NOT NULL,
    case_id TEXT NOT NULL,
    algorithm TEXT NOT NULL,
    execution TEXT NOT NULL,
    figure TEXT NOT NULL,
    machine_id INTEGER NOT NULL REFERENCES machines(id),
    UNIQUE (scenario, case_id, figure, machine_id)
);
CREATE TABLE points (
    series_id INTEGER NOT NULL REFERENCES series(id),
    commit_id INTEGER NOT NULL REFERENCES commits(id),
    recording_id INTEGER NOT NULL REFERENCES recordings(id),
    value REAL NOT NULL,
    lower REAL,
    upper REAL,
    samples TEXT,
    PRIMARY KEY (series_id, commit_id)
) WITHOUT ROWID;
";

/// An open history database.
pub struct Store {
    conn: Connection,
    path: PathBuf,
}

/// A commit of the history, in order.
#[derive(Clone, Debug, PartialEq)]
pub struct CommitRow {
    pub id: i64,
    pub sha: String,
    /// UTC, `YYYY-MM-DDTHH:MM:SSZ`.
    pub date: String,
    pub subject: String,
    /// The branches it was recorded on.
    pub branches: Vec<String>,
}

/// One series with its points, in commit order.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub scenario: String,
    pub case_id: String,
    pub algorithm: String,
    pub execution: Backend,
    pub figure: String,
    /// The machine's fingerprint.
    pub machine: String,
    /// (index into [`History::commits`], point).
    pub points: Vec<(usize, Point)>,
}

/// Everything in a database: the commits in order, the machines and every series.
#[derive(Clone, Debug, Default)]
pub struct History {
    pub commits: Vec<CommitRow>,
    /// Fingerprint → description (JSON).
    pub machines: BTreeMap<String, String>,
    pub series: Vec<Series>,
}

/// What one `record` did.
#[derive(Clone, Debug, PartialEq)]
pub struct Recorded {
    /// These results were already recorded for this commit: nothing changed.
    pub already: bool,
    pub runs: usize,
    pub points: usize,
}

/// Runs `f` again while SQLite answers "busy" without having waited (a lock upgrade that
/// would deadlock), for at most [`BUSY_TIMEOUT`] in all.
fn retry_while_busy<T>(mut f: impl FnMut() -> rusqlite::Result<T>) -> rusqlite::Result<T> {
    let start = std::time::Instant::now();
    loop {
        match f() {
            Err(e)
                if e.sqlite_error_code() == Some(ErrorCode::DatabaseBusy)
                    && start.elapsed() < BUSY_TIMEOUT =>
            {
                std::thread::sleep(Duration::from_millis(20));
            }
            r => return r,
        }
    }
}

impl Store {
    /// Opens the history at `path`; with `create`, makes a new one when there is no file (or
    /// an empty one).
    ///
    /// Errors (input errors naming the file): no file and not `create`; a file that is not an
    /// SQLite database or is damaged; an SQLite database of another application; a history of
    /// a newer schema.
    pub fn open(path: &Path, create: bool) -> Result<Store> {
        let not_history = |why: String| -> Error {
            InputError::file(path, format!("not a shadowbench history database: {why}")).into()
        };
        let len = match std::fs::metadata(path) {
            Ok(m) if m.is_dir() => return Err(not_history("it is a folder".into())),
            Ok(m) => Some(m.len()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(Error::io(path, e)),
        };
        match len {
            None | Some(0) if !create => {
                return Err(InputError::file(
                    path,
                    "no history database here (`shadowbench history record` makes one)",
                )
                .into())
            }
            Some(n) if n > 0 => {
                let mut head = [0u8; 16];
                let ok = std::fs::File::open(path)
                    .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
                    .is_ok();
                if !ok || &head != b"SQLite format 3\0" {
                    return Err(not_history("not an SQLite file".into()));
                }
            }
            _ => {}
        }
        let conn = Connection::open(path).map_err(|e| db_error(path, e))?;
        let store = Store {
            conn,
            path: path.to_path_buf(),
        };
        store
            .conn
            .busy_timeout(BUSY_TIMEOUT)
            .map_err(|e| store.err(e))?;
        store.check_or_create(create)?;
        Ok(store)
    }

    fn err(&self, e: rusqlite::Error) -> Error {
        db_error(&self.path, e)
    }

    /// Checks the marks of the file; makes the schema in a new one (one writer at a time).
    fn check_or_create(&self, create: bool) -> Result<()> {
        let c = &self.conn;
        let app: i64 = c
            .query_row("PRAGMA application_id", [], |r| r.get(0))
            .map_err(|e| self.err(e))?;
        let tables: i64 = c
            .query_row("SELECT count(*) FROM sqlite_master", [], |r| r.get(0))
            .map_err(|e| self.err(e))?;
        if app == 0 && tables == 0 && create {
            // A new file: WAL first (it needs no transaction), then the schema, made by
            // whichever writer takes the lock first. Another application's file is left as
            // it is.
            // Two new writers converting at once both hold a shared lock and want an
            // exclusive one; SQLite answers one of them "busy" at once, without waiting
            // (deadlock avoidance), so that one waits here and tries again.
            retry_while_busy(|| c.query_row("PRAGMA journal_mode = WAL", [], |_| Ok(())))
                .map_err(|e| self.err(e))?;
            c.execute_batch("BEGIN IMMEDIATE")
                .map_err(|e| self.err(e))?;
            let made = self.make_schema();
            let end = if made.is_ok() { "COMMIT" } else { "ROLLBACK" };
            c.execute_batch(end).map_err(|e| self.err(e))?;
            made?;
        }
        let app: i64 = c
            .query_row("PRAGMA application_id", [], |r| r.get(0))
            .map_err(|e| self.err(e))?;
        let foreign = |why: String| -> Error {
            InputError::file(
                &self.path,
                format!("not a shadowbench history database: {why}"),
            )
            .into()
        };
        if app != APPLICATION_ID {
            let tables: Vec<String> = c
                .prepare("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")
                .and_then(|mut s| {
                    s.query_map([], |r| r.get(0))?
                        .collect::<rusqlite::Result<Vec<String>>>()
                })
                .map_err(|e| self.err(e))?;
            return Err(foreign(if app != 0 {
                format!("an SQLite database of another application (application_id {app:#x})")
            } else if tables.is_empty() {
                "an empty SQLite database".to_string()
            } else {
                format!("an SQLite database with tables {}", tables.join(", "))
            }));
        }
        let version: i64 = c
            .query_row("PRAGMA user_version", [], |r| r.get(0))
            .map_err(|e| self.err(e))?;
        if version > SCHEMA_VERSION {
            return Err(foreign(format!(
                "written by a newer shadowbench (schema version {version}; this one reads up to \
                 {SCHEMA_VERSION})"
            )));
        }
        if version < 1 {
            return Err(foreign(format!("schema version {version}")));
        }
        Ok(())
    }

    /// Inside a write transaction: makes the schema unless another writer already did.
    fn make_schema(&self) -> Result<()> {
        let c = &self.conn;
        let app: i64 = c
            .query_row("PRAGMA application_id", [], |r| r.get(0))
            .map_err(|e| self.err(e))?;
        let tables: i64 = c
            .query_row("SELECT count(*) FROM sqlite_master", [], |r| r.get(0))
            .map_err(|e| self.err(e))?;
        if app != 0 || tables != 0 {
            return Ok(());
        }
        c.execute_batch(SCHEMA).map_err(|e| self.err(e))?;
        c.execute_batch(&format!(
            "PRAGMA application_id = {APPLICATION_ID}; PRAGMA user_version = {SCHEMA_VERSION};"
        ))
        .map_err(|e| self.err(e))?;
        for (k, v) in [
            ("format", "shadowbench history".to_string()),
            ("schema_version", SCHEMA_VERSION.to_string()),
            (
                "created_by",
                format!("shadowbench {}", env!("CARGO_PKG_VERSION")),
            ),
        ] {
            c.execute(
                "INSERT INTO meta (key, value) VALUES (?1, ?2)",
                params![k, v],
            )
            .map_err(|e| self.err(e))?;
        }
        Ok(())
    }

    /// A date as stored (UTC, `YYYY-MM-DDTHH:MM:SSZ`): `date` (ISO 8601, any offset) or now
    /// when empty. Errors: a date SQLite cannot read, naming `field`.
    pub fn utc_date(&self, field: &str, date: &str) -> Result<String> {
        let d = if date.is_empty() { "now" } else { date };
        let v: Option<String> = self
            .conn
            .query_row(
                "SELECT strftime('%Y-%m-%dT%H:%M:%SZ', ?1)",
                params![d],
                |r| r.get(0),
            )
            .map_err(|e| self.err(e))?;
        v.ok_or_else(|| {
            InputError::new(
                field,
                format!("expected an ISO 8601 date (2026-12-01T20:40:00Z), got '{date}'"),
            )
            .into()
        })
    }

    /// Records the runs of one results file (`source`, whose text is `text`) as of `commit`;
    /// `host` describes the machine ([`provenance::this_host`] or `--machine`). One
    /// transaction; see the module docs for what is replaced.
    pub fn record(
        &mut self,
        commit: &Commit,
        scenario: &str,
        source: &Path,
        text: &str,
        runs: &[RunRecord],
        host: &BTreeMap<String, Value>,
    ) -> Result<Recorded> {
        let date = self.utc_date("--date", &commit.date)?;
        let mut digest = crate::util::hash::Fnv64::default();
        digest
            .bytes(scenario.as_bytes())
            .bytes(&[0])
            .bytes(text.as_bytes())
            .bytes(&[0])
            .bytes(serde_json::to_string(host).unwrap_or_default().as_bytes());
        let digest = format!("{:016x}", digest.finish());
        let path = self.path.clone();
        let err = move |e: rusqlite::Error| db_error(&path, e);
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(&err)?;
        tx.execute(
            "INSERT INTO commits (sha, date, subject) VALUES (?1, ?2, ?3)
             ON CONFLICT (sha) DO UPDATE SET
                 subject = CASE WHEN excluded.subject <> '' THEN excluded.subject ELSE subject END",
            params![commit.sha, date, commit.subject],
        )
        .map_err(&err)?;
        let commit_id: i64 = tx
            .query_row(
                "SELECT id FROM commits WHERE sha = ?1",
                params![commit.sha],
                |r| r.get(0),
            )
            .map_err(&err)?;
        let done: Option<i64> = tx
            .query_row(
                "SELECT id FROM recordings WHERE commit_id = ?1 AND digest = ?2",
                params![commit_id, digest],
                |r| r.get(0),
            )
            .optional()
            .map_err(&err)?;
        if done.is_some() {
            tx.commit().map_err(&err)?;
            return Ok(Recorded {
                already: true,
                runs: runs.len(),
                points: 0,
            });
        }
        tx.execute(
            "INSERT INTO recordings (commit_id, branch, source, digest, recorded_at, runs, points)
             VALUES (?1, ?2, ?3, ?4, strftime('%Y-%m-%dT%H:%M:%SZ', 'now'), ?5, 0)",
            params![
                commit_id,
                commit.branch,
                source.display().to_string(),
                digest,
                runs.len() as i64
            ],
        )
        .map_err(&err)?;
        let recording = tx.last_insert_rowid();
        let mut points = 0usize;
        {
            let mut machine_ids: HashMap<String, i64> = HashMap::new();
            let mut put_machine = tx
                .prepare(
                    "INSERT INTO machines (fingerprint, description) VALUES (?1, ?2)
                     ON CONFLICT (fingerprint) DO NOTHING",
                )
                .map_err(&err)?;
            let mut get_machine = tx
                .prepare("SELECT id FROM machines WHERE fingerprint = ?1")
                .map_err(&err)?;
            let mut put_series = tx
                .prepare(
                    "INSERT INTO series (scenario, case_id, algorithm, execution, figure, machine_id)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6)
                     ON CONFLICT (scenario, case_id, figure, machine_id) DO NOTHING",
                )
                .map_err(&err)?;
            let mut get_series = tx
                .prepare(
                    "SELECT id FROM series
                     WHERE scenario = ?1 AND case_id = ?2 AND figure = ?3 AND machine_id = ?4",
                )
                .map_err(&err)?;
            let mut put_point = tx
                .prepare(
                    "INSERT INTO points (series_id, commit_id, recording_id, value, lower, upper, samples)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)
                     ON CONFLICT (series_id, commit_id) DO UPDATE SET
                         recording_id = excluded.recording_id, value = excluded.value,
                         lower = excluded.lower, upper = excluded.upper, samples = excluded.samples",
                )
                .map_err(&err)?;
            for r in runs {
                let (fingerprint, description) = provenance::machine(r, host);
                let machine_id = match machine_ids.get(&fingerprint) {
                    Some(id) => *id,
                    None => {
                        put_machine
                            .execute(params![fingerprint, description])
                            .map_err(&err)?;
                        let id: i64 = get_machine
                            .query_row(params![fingerprint], |row| row.get(0))
                            .map_err(&err)?;
                        machine_ids.insert(fingerprint, id);
                        id
                    }
                };
                let case = r.case_id();
                let algorithm = r.algorithm_label();
                for (figure, p) in figures::of_record(r) {
                    put_series
                        .execute(params![
                            scenario,
                            case,
                            algorithm,
                            r.backend.name(),
                            figure,
                            machine_id
                        ])
                        .map_err(&err)?;
                    let series_id: i64 = get_series
                        .query_row(params![scenario, case, figure, machine_id], |row| {
                            row.get(0)
                        })
                        .map_err(&err)?;
                    let samples = (!p.samples.is_empty())
                        .then(|| serde_json::to_string(&p.samples).expect("numbers serialize"));
                    put_point
                        .execute(params![
                            series_id, commit_id, recording, p.value, p.lower, p.upper, samples
                        ])
                        .map_err(&err)?;
                    points += 1;
                }
            }
        }
        tx.execute(
            "UPDATE recordings SET points = ?1 WHERE id = ?2",
            params![points as i64, recording],
        )
        .map_err(&err)?;
        tx.commit().map_err(&err)?;
        Ok(Recorded {
            already: false,
            runs: runs.len(),
            points,
        })
    }

    /// Everything in the database, commits in order (by date, then first recorded).
    pub fn load(&self) -> Result<History> {
        let c = &self.conn;
        let err = |e| self.err(e);
        let mut commits: Vec<CommitRow> = c
            .prepare("SELECT id, sha, date, subject FROM commits ORDER BY date, id")
            .and_then(|mut s| {
                s.query_map([], |r| {
                    Ok(CommitRow {
                        id: r.get(0)?,
                        sha: r.get(1)?,
                        date: r.get(2)?,
                        subject: r.get(3)?,
                        branches: vec![],
                    })
                })?
                .collect::<rusqlite::Result<Vec<_>>>()
            })
            .map_err(err)?;
        let index: HashMap<i64, usize> =
            commits.iter().enumerate().map(|(i, c)| (c.id, i)).collect();
        let branches: Vec<(i64, String)> = c
            .prepare("SELECT DISTINCT commit_id, branch FROM recordings WHERE branch <> '' ORDER BY branch")
            .and_then(|mut s| {
                s.query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?
                    .collect::<rusqlite::Result<Vec<_>>>()
            })
            .map_err(err)?;
        for (id, b) in branches {
            if let Some(&i) = index.get(&id) {
                commits[i].branches.push(b);
            }
        }
        let machines: BTreeMap<String, String> = c
            .prepare("SELECT fingerprint, description FROM machines")
            .and_then(|mut s| {
                s.query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?
                    .collect::<rusqlite::Result<BTreeMap<_, _>>>()
            })
            .map_err(err)?;
        let mut series: Vec<Series> = Vec::new();
        let mut stmt = c
            .prepare(
                "SELECT s.id, s.scenario, s.case_id, s.algorithm, s.execution, s.figure,
                        m.fingerprint, p.commit_id, p.value, p.lower, p.upper, p.samples
                 FROM points p JOIN series s ON s.id = p.series_id
                      JOIN machines m ON m.id = s.machine_id
                 ORDER BY s.id",
            )
            .map_err(err)?;
        let mut rows = stmt.query([]).map_err(err)?;
        let mut last = None;
        while let Some(r) = rows.next().map_err(err)? {
            let id: i64 = r.get(0).map_err(err)?;
            if last != Some(id) {
                last = Some(id);
                series.push(Series {
                    scenario: r.get(1).map_err(err)?,
                    case_id: r.get(2).map_err(err)?,
                    algorithm: r.get(3).map_err(err)?,
                    execution: {
                        let name: String = r.get(4).map_err(err)?;
                        Backend::parse(&name).map_err(|m| {
                            InputError::file(&self.path, format!("series {id}: execution: {m}"))
                        })?
                    },
                    figure: r.get(5).map_err(err)?,
                    machine: r.get(6).map_err(err)?,
                    points: vec![],
                });
            }
            let commit: i64 = r.get(7).map_err(err)?;
            let samples: Option<String> = r.get(11).map_err(err)?;
            let point = Point {
                value: r.get(8).map_err(err)?,
                lower: r.get(9).map_err(err)?,
                upper: r.get(10).map_err(err)?,
                samples: samples
                    .and_then(|s| serde_json::from_str(&s).ok())
                    .unwrap_or_default(),
            };
            let s = series.last_mut().expect("pushed above");
            s.points.push((index[&commit], point));
        }
        for s in &mut series {
            s.points.sort_by_key(|(i, _)| *i);
        }
        Ok(History {
            commits,
            machines,
            series,
        })
    }
}

/// An SQLite error on the database at `path`: a file that is not a database or is damaged is
/// an input error naming it; anything else fails the command (exit 1).
fn db_error(path: &Path, e: rusqlite::Error) -> Error {
    let code = e.sqlite_error_code();
    if matches!(
        code,
        Some(ErrorCode::NotADatabase) | Some(ErrorCode::DatabaseCorrupt)
    ) {
        return InputError::file(path, format!("not a shadowbench history database: {e}")).into();
    }
    Error::Other(format!("{}: history database: {e}", path.display()))
}

impl History {
    /// Whether some run (scenario and case id) was recorded on more than one machine, so
    /// outputs must name the machine beside the run.
    pub fn runs_on_several_machines(&self) -> bool {
        let mut seen: HashMap<(&str, &str), &str> = HashMap::new();
        self.series.iter().any(|s| {
            let m = seen
                .entry((s.scenario.as_str(), s.case_id.as_str()))
                .or_insert(s.machine.as_str());
            *m != s.machine
        })
    }

    /// The index of the commit `sha` names: a full id or a prefix of at least 4 digits that
    /// only one commit has. Errors name `field`.
    pub fn find_commit(&self, field: &str, sha: &str) -> Result<usize, InputError> {
        provenance::check_sha(field, sha)?;
        let sha = sha.to_lowercase();
        let found: Vec<usize> = (0..self.commits.len())
            .filter(|&i| self.commits[i].sha.starts_with(&sha))
            .collect();
        match found.as_slice() {
            [i] => Ok(*i),
            [] => Err(InputError::new(
                field,
                format!(
                    "commit '{sha}' is not in the history ({} commits)",
                    self.commits.len()
                ),
            )),
            _ => Err(InputError::new(
                field,
                format!(
                    "commit prefix '{sha}' names {} commits; give more digits",
                    found.len()
                ),
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::testdata::record;

    fn commit(sha: &str, date: &str) -> Commit {
        Commit {
            sha: sha.into(),
            branch: "main".into(),
            date: date.into(),
            subject: format!("commit {sha}"),
        }
    }

    #[test]
    fn recording_twice_changes_nothing_and_commits_are_ordered_by_date() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("h.sqlite");
        let mut s = Store::open(&db, true).unwrap();
        let runs = vec![
            record("pcss", Backend::CpuModel, 500, 32),
            record("pcss", Backend::CpuNative, 500, 32),
        ];
        let host = provenance::this_host();
        let src = Path::new("results.json");
        let b = s
            .record(
                &commit("bbbb", "2026-01-02T00:00:00Z"),
                "ci",
                src,
                "t",
                &runs,
                &host,
            )
            .unwrap();
        assert!(!b.already);
        assert!(b.points > 10);
        let again = s
            .record(
                &commit("bbbb", "2026-01-02T00:00:00Z"),
                "ci",
                src,
                "t",
                &runs,
                &host,
            )
            .unwrap();
        assert!(again.already);
        let a = s
            .record(
                &commit("aaaa", "2026-01-01T12:00:00+02:00"),
                "ci",
                src,
                "t",
                &runs,
                &host,
            )
            .unwrap();
        assert_eq!(a.points, b.points);
        drop(s);
        let h = Store::open(&db, false).unwrap().load().unwrap();
        let shas: Vec<&str> = h.commits.iter().map(|c| c.sha.as_str()).collect();
        assert_eq!(shas, ["aaaa", "bbbb"]);
        assert_eq!(h.commits[0].date, "2026-01-01T10:00:00Z");
        assert_eq!(h.commits[0].branches, ["main"]);
        assert_eq!(h.series.len(), b.points);
        assert!(h.series.iter().all(|s| s.points.len() == 2));
        assert_eq!(
            h.find_commit("--since", "bbb")
                .unwrap_err()
                .field
                .as_deref(),
            Some("--since")
        );
        assert_eq!(h.find_commit("--since", "bbbb").unwrap(), 1);
    }

    #[test]
    fn foreign_damaged_and_missing_files_are_input_errors_naming_them() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("none.sqlite");
        let e = Store::open(&missing, false).err().unwrap();
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().contains("none.sqlite"), "{e}");
        assert!(!missing.exists(), "a check must not create the file");

        let text = dir.path().join("results.json");
        std::fs::write(&text, "{\"scenario\": \"x\"}").unwrap();
        let e = Store::open(&text, true).err().unwrap();
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().contains("results.json"), "{e}");
        assert_eq!(
            std::fs::read_to_string(&text).unwrap(),
            "{\"scenario\": \"x\"}"
        );

        let other = dir.path().join("other.db");
        Connection::open(&other)
            .unwrap()
            .execute_batch("CREATE TABLE t (x); INSERT INTO t VALUES (1);")
            .unwrap();
        let e = Store::open(&other, true).err().unwrap();
        assert_eq!(e.exit_code(), 2);
        assert!(
            e.to_string().contains("other.db") && e.to_string().contains("tables t"),
            "{e}"
        );
        let mode: String = Connection::open(&other)
            .unwrap()
            .query_row("PRAGMA journal_mode", [], |r| r.get(0))
            .unwrap();
        assert_eq!(
            mode, "delete",
            "another application's file is left as it was"
        );

        let newer = dir.path().join("newer.sqlite");
        drop(Store::open(&newer, true).unwrap());
        Connection::open(&newer)
            .unwrap()
            .execute_batch("PRAGMA user_version = 9")
            .unwrap();
        let e = Store::open(&newer, false).err().unwrap();
        assert!(e.to_string().contains("schema version 9"), "{e}");

        // A history whose pages were overwritten past the header.
        let damaged = dir.path().join("damaged.sqlite");
        {
            let mut s = Store::open(&damaged, true).unwrap();
            let runs = vec![record("pcss", Backend::CpuModel, 500, 32)];
            s.record(
                &commit("cccc", "2026-01-01T00:00:00Z"),
                "ci",
                Path::new("r.json"),
                "t",
                &runs,
                &provenance::this_host(),
            )
            .unwrap();
            s.conn
                .execute_batch("PRAGMA wal_checkpoint(TRUNCATE)")
                .unwrap();
        }
        let mut bytes = std::fs::read(&damaged).unwrap();
        for b in bytes.iter_mut().skip(100) {
            *b = 0x5a;
        }
        std::fs::write(&damaged, bytes).unwrap();
        let e = Store::open(&damaged, false)
            .and_then(|s| s.load())
            .err()
            .unwrap();
        assert_eq!(e.exit_code(), 2, "{e}");
        assert!(e.to_string().contains("damaged.sqlite"), "{e}");
    }
}
