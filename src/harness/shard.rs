//! Splitting a sweep across machines: shard K of N takes every N-th planned run, starting with
//! the K-th, so the shards are disjoint, together cover the plan, and each gets a similar mix of
//! algorithms and sweep points. `shadowbench merge` joins their results.

use std::fmt;

use crate::error::InputError;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// 1-based.
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// Parses `K/N` with 1 ≤ K ≤ N; `field` names the option in errors.
    pub fn parse(field: &str, s: &str) -> Result<Shard, InputError> {
        let bad = |why: &str| InputError::new(field, format!("{why}, got '{s}'"));
        let (k, n) = s
            .split_once('/')
            .ok_or_else(|| bad("expected K/N (e.g. 1/4)"))?;
        let k: usize = k
            .trim()
            .parse()
            .map_err(|_| bad("expected K/N (e.g. 1/4)"))?;
        let n: usize = n
            .trim()
            .parse()
            .map_err(|_| bad("expected K/N (e.g. 1/4)"))?;
        if n == 0 {
            return Err(bad("the shard count N must be at least 1"));
        }
        if k == 0 || k > n {
            return Err(bad(&format!("the shard index K must be in 1..={n}")));
        }
        Ok(Shard { index: k, count: n })
    }

    /// Whether the planned run at 0-based position `i` belongs to this shard.
    pub fn includes(&self, i: usize) -> bool {
        i % self.count == self.index - 1
    }
}

/// The environment variables a batch system sets for one task of an array of tasks.
pub const SLURM_ID: &str = "SLURM_ARRAY_TASK_ID";
pub const SLURM_COUNT: &str = "SLURM_ARRAY_TASK_COUNT";
pub const SLURM_MIN: &str = "SLURM_ARRAY_TASK_MIN";
pub const SLURM_STEP: &str = "SLURM_ARRAY_TASK_STEP";
pub const K8S_INDEX: &str = "JOB_COMPLETION_INDEX";

impl Shard {
    /// The shard of this task of a batch array, from the environment (`env` looks a variable
    /// up), when `--shard` is not given:
    ///
    /// - Slurm array jobs (`sbatch --array=A-B[:S]`): K = (`SLURM_ARRAY_TASK_ID` −
    ///   `SLURM_ARRAY_TASK_MIN`) / `SLURM_ARRAY_TASK_STEP` + 1, N = `count` or else
    ///   `SLURM_ARRAY_TASK_COUNT`;
    /// - Kubernetes indexed Jobs: K = `JOB_COMPLETION_INDEX` + 1 (it is 0-based), N = `count`
    ///   (`--shard-count`, the Job's `completions`), which is then required.
    ///
    /// Returns the shard and the variable it came from; `None` when no such variable is set and
    /// no count is given. Errors name the variable and value: not a number, an index outside
    /// 1..=N, a Slurm index off the array's step, a count without an index variable.
    pub fn from_env(
        env: impl Fn(&str) -> Option<String>,
        count: Option<usize>,
    ) -> Result<Option<(Shard, &'static str)>, InputError> {
        let num = |var: &str| -> Result<Option<usize>, InputError> {
            env(var)
                .map(|v| {
                    v.trim().parse::<usize>().map_err(|_| {
                        InputError::new(var, format!("expected a whole number ≥ 0, got '{v}'"))
                    })
                })
                .transpose()
        };
        if count == Some(0) {
            return Err(InputError::new(
                "--shard-count",
                "the shard count must be at least 1, got 0",
            ));
        }
        let (index, n, var) = if let Some(id) = num(SLURM_ID)? {
            let min = num(SLURM_MIN)?.unwrap_or(0);
            let step = num(SLURM_STEP)?.unwrap_or(1).max(1);
            if id < min || (id - min) % step != 0 {
                return Err(InputError::new(
                    SLURM_ID,
                    format!(
                        "task {id} is not on the array's range from {min} in steps of {step}; \
                         give --shard K/N"
                    ),
                ));
            }
            let n = match count.or(num(SLURM_COUNT)?) {
                Some(n) => n,
                None => {
                    return Err(InputError::new(
                        SLURM_COUNT,
                        format!("{SLURM_ID} is set but {SLURM_COUNT} is not; give --shard-count N"),
                    ))
                }
            };
            ((id - min) / step + 1, n, SLURM_ID)
        } else if let Some(i) = num(K8S_INDEX)? {
            let Some(n) = count else {
                return Err(InputError::new(
                    "--shard-count",
                    format!(
                        "{K8S_INDEX} is set: give the number of shards (the Job's completions) \
                         with --shard-count N"
                    ),
                ));
            };
            (i + 1, n, K8S_INDEX)
        } else if count.is_some() {
            return Err(InputError::new(
                "--shard-count",
                format!("needs {SLURM_ID} or {K8S_INDEX} in the environment, or use --shard K/N"),
            ));
        } else {
            return Ok(None);
        };
        if n == 0 || index > n {
            return Err(InputError::new(
                var,
                format!("gives shard {index} of {n}; the index must be in 1..={n}"),
            ));
        }
        Ok(Some((Shard { index, count: n }, var)))
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_plan() {
        for n in 1..6 {
            let shards: Vec<Shard> = (1..=n)
                .map(|k| Shard::parse("--shard", &format!("{k}/{n}")).unwrap())
                .collect();
            for i in 0..23 {
                assert_eq!(shards.iter().filter(|s| s.includes(i)).count(), 1);
            }
        }
    }

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| vars.iter().find(|v| v.0 == k).map(|v| v.1.to_string())
    }

    #[test]
    fn slurm_array_tasks_become_shards_covering_the_array() {
        // sbatch --array=1-4: tasks 1..=4 are shards 1/4..4/4.
        for id in 1..=4 {
            let id_s = id.to_string();
            let vars = [
                (SLURM_ID, id_s.as_str()),
                (SLURM_COUNT, "4"),
                (SLURM_MIN, "1"),
            ];
            let (s, var) = Shard::from_env(env(&vars), None).unwrap().unwrap();
            assert_eq!((s.index, s.count, var), (id, 4, SLURM_ID));
        }
        // --array=0-10:5 → tasks 0, 5, 10 are shards 1, 2, 3 of 3.
        let vars = [
            (SLURM_ID, "10"),
            (SLURM_COUNT, "3"),
            (SLURM_MIN, "0"),
            (SLURM_STEP, "5"),
        ];
        let (s, _) = Shard::from_env(env(&vars), None).unwrap().unwrap();
        assert_eq!((s.index, s.count), (3, 3));
        // Off the step, or beyond the count: named errors.
        let vars = [(SLURM_ID, "7"), (SLURM_COUNT, "3"), (SLURM_STEP, "5")];
        let e = Shard::from_env(env(&vars), None).unwrap_err().to_string();
        assert!(e.contains(SLURM_ID) && e.contains("7"), "{e}");
        let vars = [(SLURM_ID, "5"), (SLURM_COUNT, "3")];
        let e = Shard::from_env(env(&vars), None).unwrap_err().to_string();
        assert!(e.contains("shard 6 of 3"), "{e}");
        let vars = [(SLURM_ID, "x")];
        let e = Shard::from_env(env(&vars), None).unwrap_err().to_string();
        assert!(e.contains(SLURM_ID) && e.contains("'x'"), "{e}");
    }

    #[test]
    fn kubernetes_indexed_jobs_need_the_count() {
        let vars = [(K8S_INDEX, "0")];
        let (s, var) = Shard::from_env(env(&vars), Some(3)).unwrap().unwrap();
        assert_eq!((s.index, s.count, var), (1, 3, K8S_INDEX));
        let e = Shard::from_env(env(&vars), None).unwrap_err().to_string();
        assert!(e.contains("--shard-count") && e.contains(K8S_INDEX), "{e}");
        let vars = [(K8S_INDEX, "3")];
        assert!(Shard::from_env(env(&vars), Some(3)).is_err());
        // Nothing set: no shard; a count alone is an error.
        assert_eq!(Shard::from_env(env(&[]), None).unwrap(), None);
        assert!(Shard::from_env(env(&[]), Some(2)).is_err());
        // Every index 0..N-1 gives a distinct shard: together the whole plan.
        let shards: Vec<Shard> = (0..5)
            .map(|i| {
                let i = i.to_string();
                Shard::from_env(env(&[(K8S_INDEX, i.as_str())]), Some(5))
                    .unwrap()
                    .unwrap()
                    .0
            })
            .collect();
        for i in 0..37 {
            assert_eq!(shards.iter().filter(|s| s.includes(i)).count(), 1);
        }
    }

    #[test]
    fn bad_shards_are_named() {
        for (s, why) in [
            ("0/2", "1..=2"),
            ("3/2", "1..=2"),
            ("1/0", "at least 1"),
            ("2", "K/N"),
            ("a/b", "K/N"),
        ] {
            let e = Shard::parse("--shard", s).unwrap_err().to_string();
            assert!(
                e.contains("--shard") && e.contains(why) && e.contains(s),
                "{e}"
            );
        }
    }
}
