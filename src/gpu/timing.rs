//! GPU time per pass from timestamp queries, checked against the host's time of the same
//! submission.
//!
//! **Where the timestamps go.** With `TIMESTAMP_QUERY_INSIDE_PASSES` each pass writes its
//! timestamps itself, twice at each end: right after it begins (`start`, then a second write)
//! and right before it ends (`end`, then a second write); the pass's time is `end − start`.
//! Without that feature the pass's own beginning- and end-of-pass writes are used ("around
//! passes").
//!
//! Why twice: Mesa's lavapipe (llvmpipe) does not take a timestamp when the command executes.
//! It flushes the rasterizer and then queues the query into the rasterizer's next scene, whose
//! threads write the time when that scene is flushed, i.e. at the *next* timestamp (or the end
//! of the command buffer). Only while no framebuffer has been bound (zero tiles) does it write
//! the time at once. Compute dispatches, however, run when they are executed. So once any
//! render pass has run on the device (e.g. `hard_shadow_map`'s light raster), a compute pass
//! timed around its dispatch reads both its timestamps *after* the dispatch: 0.2 ms for a
//! 400 ms pass, while the first runs of a process read right. A second write right after each
//! timestamp flushes it at once, so `start` is taken before the dispatch and `end` right after
//! it, on lavapipe and on any driver that takes timestamps at once (where the extra writes
//! cost nothing).
//!
//! **The guard.** Every reading is checked against the host's wall time of the submission that
//! held the passes (from submission to completion; [`super::Gpu::submit`]): the GPU cannot have worked
//! longer than the host waited ([`ABOVE_SLACK`]), and on a submission that kept the host
//! waiting for long a reading of a small fraction of it cannot be the passes' execution
//! ([`BELOW_FRACTION`], [`BELOW_MIN_GAP_MS`]). A reading that fails either is recorded as
//! invalid (`execution.gpu_ms_invalid`) with a warning, and the run's `gpu_ms` stays absent:
//! never charted, claimed or compared. Every record says how its GPU time was obtained
//! (`execution.gpu_time`, [`Placement::describe`]).

use std::collections::BTreeMap;
use std::ops::{Deref, DerefMut};
use std::sync::Mutex;

use crate::error::Result;

use super::readback::{resolve_buffer, words, Staging};
use super::{Gpu, Run};

/// A reading may exceed its submission's host time by this fraction (clock domains drift)...
pub const ABOVE_SLACK: f64 = 0.02;
/// ... plus this many milliseconds.
pub const ABOVE_SLACK_MS: f64 = 0.5;
/// A reading below this fraction of its submission's host time is implausible ...
pub const BELOW_FRACTION: f64 = 0.02;
/// ... when the host waited at least this many milliseconds more than the reading. Both are
/// loose on purpose: a short pass in a submission the host was slow to hand over (a debug
/// build, a loaded machine) must not be flagged; the fault they catch reads 0.02–1 ms for
/// passes of hundreds of milliseconds.
pub const BELOW_MIN_GAP_MS: f64 = 50.0;

/// Where a timer's timestamps are written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Placement {
    /// By the pass itself, twice at each end (`TIMESTAMP_QUERY_INSIDE_PASSES`).
    InsidePasses,
    /// The pass's beginning- and end-of-pass writes (`TIMESTAMP_QUERY` alone).
    AroundPasses,
}

impl Placement {
    /// The best placement `gpu` offers, or `None` without `TIMESTAMP_QUERY`.
    pub fn best(gpu: &Gpu) -> Option<Placement> {
        if gpu.queries.timestamp_inside_passes {
            Some(Placement::InsidePasses)
        } else if gpu.queries.timestamp {
            Some(Placement::AroundPasses)
        } else {
            None
        }
    }

    /// What `execution.gpu_time` says: how the GPU time was obtained.
    pub fn describe(placement: Option<Placement>) -> &'static str {
        match placement {
            Some(Placement::InsidePasses) => {
                "timestamps inside passes (two at each end, each flushed by the next)"
            }
            Some(Placement::AroundPasses) => "timestamps around passes (beginning and end of pass)",
            None => "none (the adapter has no TIMESTAMP_QUERY)",
        }
    }

    fn slots(self) -> u32 {
        match self {
            Placement::InsidePasses => 4,
            Placement::AroundPasses => 2,
        }
    }
}

/// The most queries one query set may hold (wgpu's limit).
pub const QUERY_SET_MAX: u32 = wgpu::QUERY_SET_MAX_QUERIES;

/// `count` queries split into query sets of at most [`QUERY_SET_MAX`]: each set's first
/// query and its size. The sets' results resolve to byte offsets `8 × first` (for
/// timestamps), multiples of the 256-byte resolve alignment.
pub fn query_sets(count: u32) -> impl Iterator<Item = (u32, u32)> {
    (0..count.div_ceil(QUERY_SET_MAX)).map(move |k| {
        let first = k * QUERY_SET_MAX;
        (first, (count - first).min(QUERY_SET_MAX))
    })
}

/// Timestamps of up to `passes` passes; absent when the adapter has no TIMESTAMP_QUERY.
pub struct PassTimer {
    /// The query sets, [`QUERY_SET_MAX`] queries each (the last fewer): query `q` of the timer
    /// is query `q % QUERY_SET_MAX` of set `q / QUERY_SET_MAX`.
    sets: Vec<wgpu::QuerySet>,
    resolve: wgpu::Buffer,
    staging: Staging,
    passes: u32,
    placement: Placement,
    /// The run's submission each pass was encoded in ([`PassTimer::in_submission`]).
    submission: Mutex<Vec<Option<u64>>>,
}

impl PassTimer {
    /// A timer with the best placement the adapter offers ([`Placement::best`]).
    pub fn new(gpu: &Gpu, passes: u32) -> Option<PassTimer> {
        Placement::best(gpu).map(|p| PassTimer::with_placement(gpu, passes, p))
    }

    /// A timer writing its timestamps as `placement` says (which the device must support).
    pub fn with_placement(gpu: &Gpu, passes: u32, placement: Placement) -> PassTimer {
        let count = placement.slots() * passes;
        let size = 8 * count as u64;
        PassTimer {
            sets: query_sets(count)
                .map(|(_, n)| {
                    gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                        label: Some("pass timestamps"),
                        ty: wgpu::QueryType::Timestamp,
                        count: n,
                    })
                })
                .collect(),
            resolve: resolve_buffer(gpu, "timestamp resolve", size),
            staging: Staging::new(gpu, "timestamp readback", size),
            passes,
            placement,
            submission: Mutex::new(vec![None; passes as usize]),
        }
    }

    pub fn placement(&self) -> Placement {
        self.placement
    }

    /// Notes that passes `passes` are encoded in the run's submission `submission`
    /// ([`Run::next_submission`]), whose host time their readings are checked against.
    pub fn in_submission(&self, passes: std::ops::Range<u32>, submission: u64) {
        let mut s = self.submission.lock().unwrap_or_else(|e| e.into_inner());
        for i in passes {
            s[i as usize] = Some(submission);
        }
    }

    /// The query set holding query `q` and its index there.
    fn query(&self, q: u32) -> (&wgpu::QuerySet, u32) {
        (&self.sets[(q / QUERY_SET_MAX) as usize], q % QUERY_SET_MAX)
    }

    /// The (start, end) query indices of pass `i`.
    fn ends(&self, i: u32) -> (u32, u32) {
        let k = self.placement.slots() * i;
        match self.placement {
            Placement::InsidePasses => (k, k + 2),
            Placement::AroundPasses => (k, k + 1),
        }
    }

    /// Records the resolve and the copy to the host (after all passes).
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        let count = self.placement.slots() * self.passes;
        for ((first, n), set) in query_sets(count).zip(&self.sets) {
            encoder.resolve_query_set(set, 0..n, &self.resolve, 8 * first as u64);
        }
        self.staging.copy(encoder, &self.resolve);
    }

    /// The milliseconds of each pass as the timestamps say (after submission), unchecked.
    pub fn raw_ms(&self, gpu: &Gpu) -> Result<Vec<f64>> {
        let ticks: Vec<u64> = words(&self.staging.read(gpu)?);
        let ns_per_tick = gpu.queue.get_timestamp_period() as f64;
        Ok((0..self.passes)
            .map(|i| {
                let (a, b) = self.ends(i);
                ticks[b as usize].saturating_sub(ticks[a as usize]) as f64 * ns_per_tick * 1e-6
            })
            .collect())
    }

    /// The milliseconds of each pass, checked against the host time of the submissions that
    /// held them (see the module docs).
    pub fn read(&self, gpu: &Run) -> Result<GpuTimes> {
        let ms = self.raw_ms(gpu)?;
        let submission = self
            .submission
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        let mut per_submission: BTreeMap<u64, f64> = BTreeMap::new();
        for (t, s) in ms.iter().zip(&submission) {
            if let Some(s) = s {
                *per_submission.entry(*s).or_default() += t;
            }
        }
        let invalid = per_submission.iter().find_map(|(s, &reading)| {
            let host = gpu.host_ms(*s)?;
            implausible(reading, host).map(|reason| Invalid {
                reading_ms: reading,
                host_ms: host,
                reason,
            })
        });
        Ok(GpuTimes {
            placement: Some(self.placement),
            ms: if invalid.is_some() { None } else { Some(ms) },
            invalid,
        })
    }
}

/// Why `reading_ms` of GPU time cannot be true of a submission the host waited `host_ms` for,
/// or `None` when it can.
pub fn implausible(reading_ms: f64, host_ms: f64) -> Option<String> {
    if !reading_ms.is_finite() {
        return Some(format!("GPU time {reading_ms} is not finite"));
    }
    if reading_ms > host_ms * (1.0 + ABOVE_SLACK) + ABOVE_SLACK_MS {
        return Some(format!(
            "GPU time {reading_ms:.3} ms exceeds the {host_ms:.3} ms the host waited for the \
             submission"
        ));
    }
    if reading_ms < host_ms * BELOW_FRACTION && host_ms - reading_ms > BELOW_MIN_GAP_MS {
        return Some(format!(
            "GPU time {reading_ms:.3} ms is far below the {host_ms:.3} ms the submission took \
             on the host"
        ));
    }
    None
}

/// A reading that failed the guard.
#[derive(Clone, Debug, PartialEq)]
pub struct Invalid {
    /// The GPU time the timestamps gave for one submission's passes.
    pub reading_ms: f64,
    /// The host's wall time of that submission.
    pub host_ms: f64,
    pub reason: String,
}

/// The GPU times of a run's passes, how they were obtained, and whether they were trusted.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuTimes {
    /// `None` without TIMESTAMP_QUERY.
    pub placement: Option<Placement>,
    /// Milliseconds per pass; `None` without timestamps or when the reading is invalid.
    pub ms: Option<Vec<f64>>,
    pub invalid: Option<Invalid>,
}

impl GpuTimes {
    /// The times of a run without timestamps.
    pub fn none() -> GpuTimes {
        GpuTimes {
            placement: None,
            ms: None,
            invalid: None,
        }
    }

    /// The warning of a run whose GPU time is absent, if it is.
    pub fn warning(&self) -> Option<String> {
        match (&self.placement, &self.invalid) {
            (None, _) => Some("adapter has no TIMESTAMP_QUERY: gpu_ms unavailable".into()),
            (Some(_), Some(i)) => Some(format!(
                "gpu_ms invalid, left out of charts, claims and comparisons: {}",
                i.reason
            )),
            (Some(_), None) => None,
        }
    }

    /// Writes how the GPU time was obtained (`gpu_time`) and an invalid reading
    /// (`gpu_ms_invalid`) into a record's `execution`.
    pub fn record(&self, execution: &mut BTreeMap<String, serde_json::Value>) {
        execution.insert(
            "gpu_time".into(),
            serde_json::json!(Placement::describe(self.placement)),
        );
        if let Some(i) = &self.invalid {
            execution.insert(
                "gpu_ms_invalid".into(),
                serde_json::json!({
                    "reading_ms": i.reading_ms,
                    "submission_host_ms": i.host_ms,
                    "reason": i.reason,
                }),
            );
        }
    }
}

/// The times of the passes of `timers` (one per submission, in order), each checked
/// ([`PassTimer::read`]), end to end; none without timers (no TIMESTAMP_QUERY). A run's time is
/// invalid when any submission's is (the first such is kept). The warning of an absent time
/// goes to `warnings`.
pub fn read_ms_or_warn(
    gpu: &Run,
    timers: &[PassTimer],
    warnings: &mut Vec<String>,
) -> Result<GpuTimes> {
    let mut t = GpuTimes::none();
    let mut ms = Vec::new();
    for timer in timers {
        let r = timer.read(gpu)?;
        t.placement = r.placement;
        if t.invalid.is_none() {
            t.invalid = r.invalid;
        }
        ms.extend(r.ms.into_iter().flatten());
    }
    if t.placement.is_some() && t.invalid.is_none() {
        t.ms = Some(ms);
    }
    warnings.extend(t.warning());
    Ok(t)
}

/// A pass that can write timestamps itself (`TIMESTAMP_QUERY_INSIDE_PASSES`).
pub trait WriteTimestamp {
    fn write(&mut self, set: &wgpu::QuerySet, index: u32);
}

impl WriteTimestamp for wgpu::ComputePass<'_> {
    fn write(&mut self, set: &wgpu::QuerySet, index: u32) {
        self.write_timestamp(set, index);
    }
}

impl WriteTimestamp for wgpu::RenderPass<'_> {
    fn write(&mut self, set: &wgpu::QuerySet, index: u32) {
        self.write_timestamp(set, index);
    }
}

/// A pass timed as pass `index` of a timer (when given): inside passes its timestamps are
/// written when it begins and when it is dropped; around passes, by the pass's own
/// beginning- and end-of-pass writes.
pub struct TimedPass<'e, P: WriteTimestamp> {
    pass: P,
    end: Option<(&'e PassTimer, u32)>,
}

/// A timed compute pass ([`compute_pass`]).
pub type TimedComputePass<'e> = TimedPass<'e, wgpu::ComputePass<'e>>;
/// A timed render pass ([`render_pass`]).
pub type TimedRenderPass<'e> = TimedPass<'e, wgpu::RenderPass<'e>>;

impl<'e, P: WriteTimestamp> TimedPass<'e, P> {
    /// The query set and (beginning, end) indices of a timer's pass written around it.
    fn around(timer: Option<(&'e PassTimer, u32)>) -> Option<(&'e wgpu::QuerySet, u32, u32)> {
        let (t, i) = timer.filter(|(t, _)| t.placement == Placement::AroundPasses)?;
        let (a, b) = t.ends(i);
        // A pass's queries lie in one set: a set holds a whole number of passes' slots.
        let (set, a) = t.query(a);
        Some((set, a, a + (b - t.ends(i).0)))
    }

    /// Wraps a pass just begun: writes its start timestamps inside it, where they go there.
    fn begin(mut pass: P, timer: Option<(&'e PassTimer, u32)>) -> Self {
        if let Some((t, i)) = timer {
            if t.placement == Placement::InsidePasses {
                let (a, _) = t.ends(i);
                let (set, a) = t.query(a);
                pass.write(set, a);
                pass.write(set, a + 1);
            }
        }
        TimedPass { pass, end: timer }
    }
}

/// Begins a compute pass labelled `label`, timed as pass `index` of `timer` when given.
pub fn compute_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    timer: Option<(&'e PassTimer, u32)>,
) -> TimedComputePass<'e> {
    let pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: TimedPass::<wgpu::ComputePass>::around(timer).map(|(query_set, a, b)| {
            wgpu::ComputePassTimestampWrites {
                query_set,
                beginning_of_pass_write_index: Some(a),
                end_of_pass_write_index: Some(b),
            }
        }),
    });
    TimedPass::begin(pass, timer)
}

/// Begins the render pass `desc` (whose `timestamp_writes` this sets), timed as pass `index`
/// of `timer` when given.
pub fn render_pass<'e: 'd, 'd>(
    encoder: &'e mut wgpu::CommandEncoder,
    mut desc: wgpu::RenderPassDescriptor<'d>,
    timer: Option<(&'e PassTimer, u32)>,
) -> TimedRenderPass<'e> {
    desc.timestamp_writes =
        TimedPass::<wgpu::RenderPass>::around(timer).map(|(query_set, a, b)| {
            wgpu::RenderPassTimestampWrites {
                query_set,
                beginning_of_pass_write_index: Some(a),
                end_of_pass_write_index: Some(b),
            }
        });
    TimedPass::begin(encoder.begin_render_pass(&desc), timer)
}

impl<P: WriteTimestamp> Deref for TimedPass<'_, P> {
    type Target = P;
    fn deref(&self) -> &P {
        &self.pass
    }
}

impl<P: WriteTimestamp> DerefMut for TimedPass<'_, P> {
    fn deref_mut(&mut self) -> &mut P {
        &mut self.pass
    }
}

impl<P: WriteTimestamp> Drop for TimedPass<'_, P> {
    fn drop(&mut self) {
        if let Some((t, i)) = self.end {
            if t.placement == Placement::InsidePasses {
                let (_, b) = t.ends(i);
                let (set, b) = t.query(b);
                self.pass.write(set, b);
                self.pass.write(set, b + 1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn queries_split_into_sets_of_at_most_the_limit() {
        let sets: Vec<(u32, u32)> = query_sets(2 * QUERY_SET_MAX + 8).collect();
        assert_eq!(
            sets,
            [
                (0, QUERY_SET_MAX),
                (QUERY_SET_MAX, QUERY_SET_MAX),
                (2 * QUERY_SET_MAX, 8)
            ]
        );
        assert_eq!(query_sets(QUERY_SET_MAX).count(), 1);
        assert_eq!(query_sets(0).count(), 0);
        // Each set resolves at a multiple of the resolve alignment.
        let aligned =
            |first: u32| (8 * first as u64).is_multiple_of(wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT);
        assert!(sets.iter().all(|(first, _)| aligned(*first)));
    }

    #[test]
    fn readings_above_the_host_wait_or_far_below_a_long_one_are_implausible() {
        // The readings: 0.16 ms for a 400 ms submission.
        assert!(implausible(0.16, 400.0).unwrap().contains("far below"));
        assert!(implausible(197.0, 200.0).is_none());
        // Longer than the host waited.
        assert!(implausible(12.0, 5.0).unwrap().contains("exceeds"));
        assert!(implausible(5.05, 5.0).is_none());
        // A short pass in a short submission: submission overhead dominates, still plausible.
        assert!(implausible(0.01, 2.0).is_none());
        assert!(implausible(0.75, 21.0).is_none());
        assert!(implausible(f64::NAN, 2.0).is_some());
    }
}
