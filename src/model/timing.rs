//! The timing model: from what a core executed to cycles, and from cores to a phase's makespan.
//! The formulas are documented with their reasoning in `docs/model.md`.

use super::cache::CacheStats;
use super::config::MachineConfig;

/// What one modelled core executed in one step (the sum over its tasks).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CoreWork {
    pub tasks: u64,
    pub vector_ops: u64,
    /// Sum over vector instructions of their active lanes.
    pub active_lanes: u64,
    pub scalar_ops: u64,
    /// Contiguous loads and stores, and the cache lines they touched.
    pub loads: u64,
    pub stores: u64,
    pub access_lines: u64,
    pub gathers: u64,
    pub gather_lines: u64,
    pub scatters: u64,
    pub scatter_lines: u64,
    pub atomics: u64,
    pub cache: CacheStats,
}

impl CoreWork {
    /// Cycles the core's issue pipe is busy: `vector·c_v + active_lanes·c_lane + scalar·c_s
    /// + lines(load/store)·c_m + lines(gather/scatter)·c_gl + (gathers + scatters)·c_g
    /// + atomics·c_a` (`c_lane` and `c_g` are 0 on Larrabee).
    pub fn issue_cycles(&self, m: &MachineConfig) -> f64 {
        let k = &m.costs;
        self.vector_ops as f64 * k.vector
            + self.active_lanes as f64 * k.lane
            + self.scalar_ops as f64 * k.scalar
            + self.access_lines as f64 * k.vector_memory
            + (self.gather_lines + self.scatter_lines) as f64 * k.gather_line
            + (self.gathers + self.scatters) as f64 * k.gather
            + self.atomics as f64 * k.atomic
    }

    /// Cycles its threads wait on memory (an L1 hit costs no more than its issue cycle), over
    /// the memory-level parallelism `mlp` (1 unless the machine states it):
    /// without an L3 `(l2_hits·L2 + l2_misses·(L2 + DRAM)) / mlp`; with a shared L3
    /// `(l2_hits·L2 + l3_hits·(L2 + L3) + l3_misses·(L2 + L3 + DRAM)) / mlp`.
    pub fn stall_cycles(&self, m: &MachineConfig) -> f64 {
        let c = &self.cache;
        let l2 = m.l2.latency_cycles;
        let stall = match &m.l3 {
            None => c.l2_hits as f64 * l2 + c.l2_misses as f64 * (l2 + m.dram_latency_cycles),
            Some(l3) => {
                let l3 = l2 + l3.latency_cycles;
                c.l2_hits as f64 * l2
                    + c.l3_hits as f64 * l3
                    + c.l3_misses as f64 * (l3 + m.dram_latency_cycles)
            }
        };
        stall / m.mlp()
    }

    /// Cycles of the core: `max(issue, (issue + stall) / T)`. With T hardware threads the core
    /// issues from whichever thread is ready, so stalls of one thread hide behind the work of
    /// the others until the issue pipe is saturated; with T = 1 nothing is hidden.
    pub fn cycles(&self, m: &MachineConfig) -> f64 {
        let issue = self.issue_cycles(m);
        issue.max((issue + self.stall_cycles(m)) / m.threads_per_core as f64)
    }

    pub fn add(&mut self, o: &CoreWork) {
        self.tasks += o.tasks;
        self.vector_ops += o.vector_ops;
        self.active_lanes += o.active_lanes;
        self.scalar_ops += o.scalar_ops;
        self.loads += o.loads;
        self.stores += o.stores;
        self.access_lines += o.access_lines;
        self.gathers += o.gathers;
        self.gather_lines += o.gather_lines;
        self.scatters += o.scatters;
        self.scatter_lines += o.scatter_lines;
        self.atomics += o.atomics;
        self.cache.add(&o.cache);
    }
}

/// The time of one step (a barrier-to-barrier piece of a phase) on the machine.
#[derive(Clone, Debug, PartialEq)]
pub struct StepTime {
    /// Cycles of each core.
    pub core_cycles: Vec<f64>,
    /// Cycles the chip's DRAM bandwidth needs for the step's traffic.
    pub bandwidth_cycles: f64,
    /// `max(max_core, bandwidth) + barrier`.
    pub cycles: f64,
}

impl StepTime {
    pub fn new(m: &MachineConfig, cores: &[CoreWork]) -> StepTime {
        let core_cycles: Vec<f64> = cores.iter().map(|c| c.cycles(m)).collect();
        let dram_lines: u64 = cores
            .iter()
            .map(|c| c.cache.dram_read_lines + c.cache.dram_write_lines)
            .sum();
        let bandwidth_cycles =
            (dram_lines * u64::from(m.line_bytes)) as f64 / m.dram_bytes_per_cycle();
        let busiest = core_cycles.iter().copied().fold(0.0, f64::max);
        StepTime {
            cycles: busiest.max(bandwidth_cycles) + m.barrier_cycles,
            core_cycles,
            bandwidth_cycles,
        }
    }

    pub fn ms(&self, m: &MachineConfig) -> f64 {
        self.cycles / m.cycles_per_ms()
    }

    /// Busiest core over the mean core (1 = perfectly balanced).
    pub fn load_imbalance(&self) -> f64 {
        let n = self.core_cycles.len().max(1) as f64;
        let mean = self.core_cycles.iter().sum::<f64>() / n;
        let max = self.core_cycles.iter().copied().fold(0.0, f64::max);
        if mean > 0.0 {
            max / mean
        } else {
            1.0
        }
    }
}

/// Assigns tasks to `cores` by the deterministic list scheduler "longest estimated task first,
/// to the least-loaded core" (LPT): tasks in order of decreasing `weight` (ties by index) each
/// go to the core with the least estimated work so far (ties to the lowest core). Returns, per
/// core, its task indices in the order it runs them.
pub fn schedule(weights: &[u64], cores: usize) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..weights.len()).collect();
    order.sort_by_key(|&t| (std::cmp::Reverse(weights[t]), t));
    let mut load = vec![0u64; cores];
    let mut lists = vec![Vec::new(); cores];
    for t in order {
        let c = (0..cores).min_by_key(|&c| (load[c], c)).expect("cores > 0");
        // Every task costs something, even when its estimate is zero.
        load[c] += weights[t].max(1);
        lists[c].push(t);
    }
    lists
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn threads_hide_stalls_until_issue_bound() {
        let mut m = MachineConfig::larrabee(1);
        let w = CoreWork {
            vector_ops: 100,
            cache: CacheStats {
                l2_hits: 30,
                ..Default::default()
            },
            ..Default::default()
        };
        m.threads_per_core = 1;
        assert_eq!(w.cycles(&m), 100.0 + 30.0 * m.l2.latency_cycles);
        m.threads_per_core = 4;
        assert_eq!(w.cycles(&m), (100.0 + 300.0) / 4.0);
        m.threads_per_core = 16;
        assert_eq!(w.cycles(&m), 100.0);
    }

    #[test]
    fn an_l3_and_memory_parallelism_shorten_the_stalls() {
        let mut m = MachineConfig::larrabee(1);
        m.threads_per_core = 1;
        let w = CoreWork {
            vector_ops: 100,
            cache: CacheStats {
                l2_hits: 10,
                l2_misses: 30,
                l3_hits: 20,
                l3_misses: 10,
                ..Default::default()
            },
            ..Default::default()
        };
        // Without an L3 every L2 miss goes to DRAM: 10·10 + 30·(10 + 200).
        assert_eq!(w.cycles(&m), 100.0 + 100.0 + 30.0 * 210.0);
        m.l3 = Some(crate::model::config::CacheConfig {
            size_bytes: 1 << 20,
            ways: 16,
            latency_cycles: 40.0,
        });
        // 10·10 + 20·(10 + 40) + 10·(10 + 40 + 200).
        let stall = 100.0 + 1000.0 + 2500.0;
        assert_eq!(w.cycles(&m), 100.0 + stall);
        m.memory_parallelism = Some(4.0);
        assert_eq!(w.cycles(&m), 100.0 + stall / 4.0);
    }

    #[test]
    fn a_lane_cost_charges_every_active_lane() {
        // 10 instructions with 100 active lanes in all, at 2 cycles per instruction and 0.5
        // per lane: 20 + 50 cycles; Larrabee (no lane cost) issues them in 10.
        let mut m = MachineConfig::larrabee(1);
        let w = CoreWork {
            vector_ops: 10,
            active_lanes: 100,
            ..Default::default()
        };
        assert_eq!(w.issue_cycles(&m), 10.0);
        m.costs.vector = 2.0;
        m.costs.lane = 0.5;
        assert_eq!(w.issue_cycles(&m), 70.0);
    }

    #[test]
    fn lpt_balances_and_uses_every_task_once() {
        let w = [5, 3, 3, 2, 2, 2, 1];
        let lists = schedule(&w, 3);
        let mut all: Vec<usize> = lists.iter().flatten().copied().collect();
        all.sort();
        assert_eq!(all, (0..w.len()).collect::<Vec<_>>());
        let loads: Vec<u64> = lists
            .iter()
            .map(|l| l.iter().map(|&t| w[t]).sum())
            .collect();
        let total: u64 = w.iter().sum();
        assert!(*loads.iter().max().unwrap() <= total / 3 + 5, "{loads:?}");
    }
}
