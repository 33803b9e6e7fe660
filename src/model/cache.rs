//! Per-core caches: an L1 data cache and the core's partition of the L2 (004 §3.1: "a per-core
//! L1, large L2 partitioned across cores"), and on machines that have one a last-level cache
//! shared by all cores ([`SharedCache`], the L3 of current CPUs).
//!
//! Every level is set-associative with true LRU replacement, write-allocate and write-back.
//! Each core's caches see only that core's accesses, in the core's task order, so their state
//! does not depend on how the host schedules the simulation. The shared level sees the cores'
//! L2 misses and write-backs after each step, interleaved one per core in turn in core order,
//! so it too is deterministic. Coherence traffic between L2 partitions is not modelled: the
//! sort-middle pipeline gives each core its own tiles, so cores rarely share written lines
//! within a phase.

use super::config::{CacheConfig, MachineConfig};

/// One set-associative LRU cache level.
#[derive(Clone, Debug)]
pub struct Cache {
    ways: usize,
    /// Sets; a line's set is `line mod sets` (a mask when `sets` is a power of two).
    sets: u64,
    set_mask: Option<u64>,
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
    /// The line evicted, if any.
    pub evicted: Option<u64>,
}

impl Cache {
    pub fn new(machine: &MachineConfig, c: &CacheConfig) -> Cache {
        let sets = machine.sets(c).max(1) as usize;
        let ways = c.ways as usize;
        Cache {
            ways,
            sets: sets as u64,
            set_mask: sets.is_power_of_two().then_some(sets as u64 - 1),
            tags: vec![u64::MAX; sets * ways],
            dirty: vec![false; sets * ways],
        }
    }

    /// The first entry of `line`'s set.
    fn set_of(&self, line: u64) -> usize {
        let set = match self.set_mask {
            Some(mask) => line & mask,
            None => line % self.sets,
        };
        set as usize * self.ways
    }

    /// Accesses cache line number `line`; `write` marks it dirty.
    pub fn access(&mut self, line: u64, write: bool) -> Outcome {
        let set = self.set_of(line);
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
                    evicted: None,
                }
            }
            None => {
                let victim = tags[self.ways - 1];
                let evicted = (victim != u64::MAX).then_some(victim);
                let evicted_dirty = evicted.is_some() && dirty[self.ways - 1];
                tags.rotate_right(1);
                dirty.rotate_right(1);
                tags[0] = line;
                dirty[0] = write;
                Outcome {
                    hit: false,
                    dirty_eviction: evicted_dirty,
                    evicted,
                }
            }
        }
    }

    /// Marks `line` dirty without touching the LRU order; false when it is not cached.
    pub fn mark_dirty(&mut self, line: u64) -> bool {
        let set = self.set_of(line);
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
        self.dirty_line_list().count() as u64
    }

    /// The dirty lines, in set and way order.
    fn dirty_line_list(&self) -> impl Iterator<Item = u64> + '_ {
        self.tags
            .iter()
            .zip(&self.dirty)
            .filter(|(&t, &d)| t != u64::MAX && d)
            .map(|(&t, _)| t)
    }
}

/// Hits and misses of one core's hierarchy.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CacheStats {
    pub l1_hits: u64,
    pub l1_misses: u64,
    pub l2_hits: u64,
    pub l2_misses: u64,
    /// L2 misses served by the shared L3, and those it missed (0 without an L3).
    pub l3_hits: u64,
    pub l3_misses: u64,
    /// Lines read from DRAM (L2 misses, or L3 misses with an L3) and written to it (dirty
    /// evictions from the last level).
    pub dram_read_lines: u64,
    pub dram_write_lines: u64,
}

impl CacheStats {
    /// `self − before`, field by field (what happened between two readings).
    pub fn since(&self, before: &CacheStats) -> CacheStats {
        CacheStats {
            l1_hits: self.l1_hits - before.l1_hits,
            l1_misses: self.l1_misses - before.l1_misses,
            l2_hits: self.l2_hits - before.l2_hits,
            l2_misses: self.l2_misses - before.l2_misses,
            l3_hits: self.l3_hits - before.l3_hits,
            l3_misses: self.l3_misses - before.l3_misses,
            dram_read_lines: self.dram_read_lines - before.dram_read_lines,
            dram_write_lines: self.dram_write_lines - before.dram_write_lines,
        }
    }

    /// Adds `o` field by field.
    pub fn add(&mut self, o: &CacheStats) {
        self.l1_hits += o.l1_hits;
        self.l1_misses += o.l1_misses;
        self.l2_hits += o.l2_hits;
        self.l2_misses += o.l2_misses;
        self.l3_hits += o.l3_hits;
        self.l3_misses += o.l3_misses;
        self.dram_read_lines += o.dram_read_lines;
        self.dram_write_lines += o.dram_write_lines;
    }
}

/// What an L2 sends to the shared L3: a line it missed (a read) or a dirty line it evicted (a
/// write-back), encoded as `line << 1 | write_back`.
type Outbound = Vec<u64>;

/// The L1 and L2 partition of one core.
#[derive(Clone, Debug)]
pub struct CoreCaches {
    l1: Cache,
    l2: Cache,
    pub stats: CacheStats,
    /// With a shared L3: the L2's misses and write-backs since the last replay
    /// ([`SharedCache::replay`]); the DRAM counts are then the L3's. `None`: the L2 is the last
    /// level and talks to DRAM itself.
    outbound: Option<Outbound>,
}

impl CoreCaches {
    /// Bytes the model allocates for one core's L1 and L2 (a tag and a dirty flag per line,
    /// [`Cache::new`]), for the memory estimate made before a run.
    pub fn bytes(machine: &MachineConfig) -> u64 {
        (lines(machine, &machine.l1) + lines(machine, &machine.l2)) * BYTES_PER_LINE
    }

    pub fn new(machine: &MachineConfig) -> CoreCaches {
        CoreCaches {
            l1: Cache::new(machine, &machine.l1),
            l2: Cache::new(machine, &machine.l2),
            stats: CacheStats::default(),
            outbound: machine.l3.is_some().then(Vec::new),
        }
    }

    /// One access to `line`. Dirtiness is tracked in L2 only (the L1 behaves as write-through
    /// to its L2 partition, which holds the line dirty until it is evicted to DRAM); a write
    /// that hits a line the L2 has already evicted goes straight to DRAM.
    pub fn access(&mut self, line: u64, write: bool) {
        if self.l1.access(line, false).hit {
            self.stats.l1_hits += 1;
            if write && !self.l2.mark_dirty(line) {
                self.write_through_miss(line);
            }
            return;
        }
        let s = &mut self.stats;
        s.l1_misses += 1;
        let o2 = self.l2.access(line, write);
        if o2.hit {
            s.l2_hits += 1;
        } else {
            s.l2_misses += 1;
        }
        match self.outbound.as_mut() {
            None => {
                s.dram_read_lines += u64::from(!o2.hit);
                s.dram_write_lines += u64::from(o2.dirty_eviction);
            }
            Some(out) => {
                if !o2.hit {
                    out.push(line << 1);
                }
                if let (true, Some(victim)) = (o2.dirty_eviction, o2.evicted) {
                    out.push(victim << 1 | 1);
                }
            }
        }
    }

    /// Writes back what is still dirty in L2 (end of frame): to DRAM, or with a shared L3 into
    /// the outbound stream (replayed by [`SharedCache::flush`]).
    pub fn flush(&mut self) {
        match self.outbound.as_mut() {
            None => self.stats.dram_write_lines += self.l2.dirty_lines(),
            Some(out) => out.extend(self.l2.dirty_line_list().map(|l| l << 1 | 1)),
        }
    }

    /// A write that hit L1 but whose line the L2 no longer holds goes to the level below.
    fn write_through_miss(&mut self, line: u64) {
        match self.outbound.as_mut() {
            None => self.stats.dram_write_lines += 1,
            Some(out) => out.push(line << 1 | 1),
        }
    }
}

/// Tag and dirty-flag bytes the model allocates per cache line ([`Cache::new`]).
const BYTES_PER_LINE: u64 = (std::mem::size_of::<u64>() + std::mem::size_of::<bool>()) as u64;

fn lines(machine: &MachineConfig, c: &CacheConfig) -> u64 {
    u64::from(machine.sets(c)) * u64::from(c.ways)
}

/// The last-level cache shared by all cores (an L3), write-back and write-allocate, filled on an
/// L2 miss and written by the L2s' dirty evictions (a write-back that misses allocates the line
/// without reading DRAM: the whole line is written). It sees the cores' L2 traffic after each
/// step ([`SharedCache::replay`]), so the cores' own simulations stay independent and run in
/// parallel; the interleaving (one event per core in turn, in core order) is a fixed stand-in for
/// the cores running at the same time.
#[derive(Clone, Debug)]
pub struct SharedCache {
    cache: Cache,
}

impl SharedCache {
    /// Bytes the model allocates for the shared level of `machine` (0 without one).
    pub fn bytes(machine: &MachineConfig) -> u64 {
        machine
            .l3
            .as_ref()
            .map_or(0, |c| lines(machine, c) * BYTES_PER_LINE)
    }

    /// The shared level of `machine`, if it has one.
    pub fn new(machine: &MachineConfig) -> Option<SharedCache> {
        machine.l3.as_ref().map(|c| SharedCache {
            cache: Cache::new(machine, c),
        })
    }

    /// Runs the L2 traffic the `cores` sent since the last replay through the shared level, one
    /// event per core in turn, in core order; each core's `l3_hits`, `l3_misses` and DRAM lines
    /// grow by what its own events caused. Empties the cores' outbound streams.
    pub fn replay(&mut self, cores: &mut [&mut CoreCaches]) {
        let streams: Vec<Outbound> = cores
            .iter_mut()
            .map(|c| c.outbound.as_mut().map(std::mem::take).unwrap_or_default())
            .collect();
        let longest = streams.iter().map(Vec::len).max().unwrap_or(0);
        for i in 0..longest {
            for (core, stream) in cores.iter_mut().zip(&streams) {
                let Some(&event) = stream.get(i) else {
                    continue;
                };
                let (line, write_back) = (event >> 1, event & 1 == 1);
                let o = self.cache.access(line, write_back);
                let s = &mut core.stats;
                if !write_back {
                    if o.hit {
                        s.l3_hits += 1;
                    } else {
                        s.l3_misses += 1;
                        s.dram_read_lines += 1;
                    }
                }
                s.dram_write_lines += u64::from(o.dirty_eviction);
            }
        }
    }

    /// End of frame: the cores' L2s write back what is dirty ([`CoreCaches::flush`] first), then
    /// what is dirty here goes to DRAM; those lines are counted on `cores[0]`.
    pub fn flush(&mut self, cores: &mut [&mut CoreCaches]) {
        self.replay(cores);
        if let Some(first) = cores.first_mut() {
            first.stats.dram_write_lines += self.cache.dirty_lines();
        }
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

    /// `tiny()` with a shared 8 KiB 4-way L3 (32 sets).
    fn tiny_l3() -> MachineConfig {
        let mut m = tiny();
        m.l3 = Some(CacheConfig {
            size_bytes: 8192,
            ways: 4,
            latency_cycles: 30.0,
        });
        m
    }

    #[test]
    fn a_working_set_larger_than_l2_hits_in_the_shared_l3() {
        let m = tiny_l3();
        let mut l3 = SharedCache::new(&m).unwrap();
        let mut c = CoreCaches::new(&m);
        // 64 lines: twice the L2 (32 lines), half the L3 (128 lines), read three times.
        for _ in 0..3 {
            for line in 0..64 {
                c.access(line, false);
            }
            l3.replay(&mut [&mut c]);
        }
        // Every access misses L1 and L2 (LRU over a cyclic set twice their size); the first
        // pass misses L3 too, the other two hit it.
        assert_eq!(c.stats.l2_misses, 192);
        assert_eq!((c.stats.l3_misses, c.stats.l3_hits), (64, 128));
        assert_eq!(c.stats.dram_read_lines, 64);
    }

    #[test]
    fn cores_share_the_l3_and_only_the_last_level_writes_dram() {
        let m = tiny_l3();
        let mut l3 = SharedCache::new(&m).unwrap();
        let (mut a, mut b) = (CoreCaches::new(&m), CoreCaches::new(&m));
        // Both cores read the same 8 lines: one DRAM read per line, the second core hits L3.
        for line in 0..8 {
            a.access(line, false);
            b.access(line, false);
        }
        l3.replay(&mut [&mut a, &mut b]);
        assert_eq!((a.stats.l3_misses, b.stats.l3_hits), (8, 8));
        assert_eq!(a.stats.dram_read_lines + b.stats.dram_read_lines, 8);
        // Core a writes 4 lines; at the end they pass through L3 to DRAM exactly once.
        for line in 100..104 {
            a.access(line, true);
        }
        a.flush();
        b.flush();
        l3.flush(&mut [&mut a, &mut b]);
        assert_eq!(a.stats.dram_write_lines + b.stats.dram_write_lines, 4);
        assert_eq!(a.stats.dram_read_lines, 8 + 4);
    }

    #[test]
    fn sets_need_not_be_a_power_of_two() {
        // 3 sets × 2 ways: lines 0, 3, 6 share set 0.
        let mut m = tiny();
        m.l1 = CacheConfig {
            size_bytes: 3 * 2 * 64,
            ways: 2,
            latency_cycles: 1.0,
        };
        m.validate().unwrap();
        let mut c = Cache::new(&m, &m.l1);
        assert!(!c.access(0, false).hit);
        assert!(!c.access(3, false).hit);
        assert!(!c.access(1, false).hit); // another set: evicts nothing of set 0
        assert!(c.access(0, false).hit);
        let o = c.access(6, false); // evicts 3, the least recently used of set 0
        assert_eq!((o.hit, o.evicted), (false, Some(3)));
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
