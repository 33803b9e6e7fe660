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
