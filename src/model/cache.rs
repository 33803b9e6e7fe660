//! Per-core caches: an L1 data cache and the core's partition of the L2 (004 §3.1: "a per-core
//! L1, large L2 partitioned across cores").
//!
//! Both levels are set-associative with true LRU replacement, write-allocate and write-back.
//! Each core's caches see only that core's accesses, in the core's task order, so their state
//! does not depend on how the host schedules the simulation. Coherence traffic between L2
//! partitions is not modelled: the sort-middle pipeline gives each core its own tiles, so cores
//! rarely share written lines within a phase.

use super::config::{CacheConfig, MachineConfig};

/// One set-associative LRU cache level.
#[derive(Clone, Debug)]
pub struct Cache {
    ways: usize,
    set_mask: u64,
    /// Per set, `ways` entries ordered most- to least-recently used; `u64::MAX` is empty.
    tags: Vec<u64>,
    dirty: Vec<bool>,
}

/// What one access did at one level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Outcome {
    pub hit: bool,
    /// A dirty line was evicted (to be written to the level below).
    pub dirty_eviction: bool,
}

impl Cache {
    pub fn new(machine: &MachineConfig, c: &CacheConfig) -> Cache {
        let sets = machine.sets(c) as usize;
        let ways = c.ways as usize;
        Cache {
            ways,
            set_mask: sets as u64 - 1,
            tags: vec![u64::MAX; sets * ways],
            dirty: vec![false; sets * ways],
        }
    }

    /// Accesses cache line number `line`; `write` marks it dirty.
    pub fn access(&mut self, line: u64, write: bool) -> Outcome {
        let set = (line & self.set_mask) as usize * self.ways;
        let tags = &mut self.tags[set..set + self.ways];
        let dirty = &mut self.dirty[set..set + self.ways];
        match tags.iter().position(|&t| t == line) {
            Some(way) => {
                tags[..=way].rotate_right(1);
                dirty[..=way].rotate_right(1);
                dirty[0] |= write;
                Outcome {
                    hit: true,
                    dirty_eviction: false,
                }
            }
            None => {
                let evicted_dirty = tags[self.ways - 1] != u64::MAX && dirty[self.ways - 1];
                tags.rotate_right(1);
                dirty.rotate_right(1);
                tags[0] = line;
                dirty[0] = write;
                Outcome {
                    hit: false,
                    dirty_eviction: evicted_dirty,
                }
            }
        }
    }

    /// Marks `line` dirty without touching the LRU order; false when it is not cached.
    pub fn mark_dirty(&mut self, line: u64) -> bool {
        let set = (line & self.set_mask) as usize * self.ways;
        match self.tags[set..set + self.ways]
            .iter()
            .position(|&t| t == line)
        {
            Some(way) => {
                self.dirty[set + way] = true;
                true
            }
            None => false,
        }
    }

    /// Lines still dirty (written back when the frame ends).
    pub fn dirty_lines(&self) -> u64 {
        self.tags
            .iter()
            .zip(&self.dirty)
            .filter(|(&t, &d)| t != u64::MAX && d)
            .count() as u64
    }
}

/// Hits and misses of one core's hierarchy.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CacheStats {
    pub l1_hits: u64,
    pub l1_misses: u64,
    pub l2_hits: u64,
    pub l2_misses: u64,
    /// Lines read from DRAM (L2 misses) and written to it (dirty L2 evictions).
    pub dram_read_lines: u64,
    pub dram_write_lines: u64,
}

/// The L1 and L2 partition of one core.
#[derive(Clone, Debug)]
pub struct CoreCaches {
    l1: Cache,
    l2: Cache,
    pub stats: CacheStats,
}

impl CoreCaches {
    /// Bytes the model allocates for one core's L1 and L2 (a tag and a dirty flag per line,
    /// [`Cache::new`]), for the memory estimate made before a run.
    pub fn bytes(machine: &MachineConfig) -> u64 {
        let lines = |c: &CacheConfig| machine.sets(c) as u64 * c.ways as u64;
        (lines(&machine.l1) + lines(&machine.l2))
            * (std::mem::size_of::<u64>() + std::mem::size_of::<bool>()) as u64
    }

    pub fn new(machine: &MachineConfig) -> CoreCaches {
        CoreCaches {
            l1: Cache::new(machine, &machine.l1),
            l2: Cache::new(machine, &machine.l2),
            stats: CacheStats::default(),
        }
    }

    /// One access to `line`. Dirtiness is tracked in L2 only (the L1 behaves as write-through
    /// to its L2 partition, which holds the line dirty until it is evicted to DRAM); a write
    /// that hits a line the L2 has already evicted goes straight to DRAM.
    pub fn access(&mut self, line: u64, write: bool) {
        let s = &mut self.stats;
        if self.l1.access(line, false).hit {
            s.l1_hits += 1;
            if write && !self.l2.mark_dirty(line) {
                s.dram_write_lines += 1;
            }
            return;
        }
        s.l1_misses += 1;
        let o2 = self.l2.access(line, write);
        if o2.hit {
            s.l2_hits += 1;
        } else {
            s.l2_misses += 1;
            s.dram_read_lines += 1;
        }
        s.dram_write_lines += u64::from(o2.dirty_eviction);
    }

    /// Writes back what is still dirty in L2 (end of frame).
    pub fn flush(&mut self) {
        self.stats.dram_write_lines += self.l2.dirty_lines();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> MachineConfig {
        let mut m = MachineConfig::larrabee(1);
        // 4 sets × 2 ways of 64-byte lines.
        m.l1 = CacheConfig {
            size_bytes: 512,
            ways: 2,
            latency_cycles: 1.0,
        };
        m.l2 = CacheConfig {
            size_bytes: 2048,
            ways: 4,
            latency_cycles: 10.0,
        };
        m
    }

    #[test]
    fn lru_keeps_the_recently_used_line_of_a_set() {
        let m = tiny();
        let mut c = Cache::new(&m, &m.l1);
        // Lines 0, 4, 8 map to set 0 of a 4-set cache.
        assert!(!c.access(0, false).hit);
        assert!(!c.access(4, false).hit);
        assert!(c.access(0, false).hit);
        assert!(!c.access(8, false).hit); // evicts 4, the least recently used
        assert!(c.access(0, false).hit);
        assert!(!c.access(4, false).hit);
    }

    #[test]
    fn a_working_set_larger_than_l1_hits_in_l2() {
        let m = tiny();
        let mut c = CoreCaches::new(&m);
        // 16 lines: twice the L1 (8 lines), half the L2 (32 lines).
        for _ in 0..3 {
            for line in 0..16 {
                c.access(line, false);
            }
        }
        assert_eq!(c.stats.l2_misses, 16);
        assert_eq!(c.stats.l1_hits, 0);
        assert_eq!(c.stats.l2_hits, 32);
    }

    #[test]
    fn dirty_lines_are_written_back_once() {
        let m = tiny();
        let mut c = CoreCaches::new(&m);
        for line in 0..4 {
            c.access(line, true);
        }
        c.flush();
        assert_eq!(c.stats.dram_write_lines, 4);
        assert_eq!(c.stats.dram_read_lines, 4);
    }
}
