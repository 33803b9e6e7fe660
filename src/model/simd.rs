//! The kernel programming model: 16 lanes under a mask (004 §3.1: "16-wide SIMD units ...
//! conditional execution via vector element masking ... scatter / gather memory operations").
//!
//! Kernels are ordinary Rust over `[T; 16]` lane arrays, generic over a [`Probe`]. They tell the
//! probe what the modelled machine would execute: vector instructions with their lane mask,
//! scalar instructions, memory accesses by address, gathers and scatters, atomics. The model's
//! probe counts and simulates caches; [`NoProbe`] compiles every call away, which is the
//! `cpu-native` execution of the very same kernel code.

/// Lanes of the modelled vector unit.
pub const LANES: usize = 16;

/// One value per lane.
pub type Lanes<T> = [T; LANES];

/// The items `range` in vectors of [`LANES`]: per vector its first item, its item count and the
/// mask of its live lanes (the last vector may be partial).
pub fn lane_groups(range: std::ops::Range<usize>) -> impl Iterator<Item = (usize, usize, Mask)> {
    let end = range.end;
    range.step_by(LANES).map(move |group| {
        let k = (end - group).min(LANES);
        (group, k, Mask::first(k))
    })
}

/// The items of task `task` when `n` items are cut into tasks of `size` items (the last task
/// may be short).
pub fn task_items(task: usize, size: usize, n: usize) -> std::ops::Range<usize> {
    (task * size).min(n)..((task + 1) * size).min(n)
}

/// The weights (items per task) of `n` items cut into tasks of `size`, as
/// [`crate::model::Machine::run_step`] takes them.
pub fn task_weights(n: usize, size: usize) -> Vec<u64> {
    (0..n.div_ceil(size))
        .map(|t| task_items(t, size, n).len() as u64)
        .collect()
}

/// Which lanes of a vector instruction are active.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Mask(pub u16);

impl Mask {
    pub const NONE: Mask = Mask(0);
    pub const ALL: Mask = Mask(u16::MAX);

    /// The mask of lanes where `f(lane)` holds.
    pub fn from_fn(mut f: impl FnMut(usize) -> bool) -> Mask {
        let mut m = 0u16;
        for l in 0..LANES {
            m |= u16::from(f(l)) << l;
        }
        Mask(m)
    }

    /// The first `n` lanes (a partial vector at the end of an array).
    pub fn first(n: usize) -> Mask {
        if n >= LANES {
            Mask::ALL
        } else {
            Mask(((1u32 << n) - 1) as u16)
        }
    }

    /// The mask of the lanes where `lanes[l]` is true (a compare's result; built without a
    /// branch per lane).
    #[inline]
    pub fn from_lanes(lanes: &[bool; LANES]) -> Mask {
        let mut m = 0u16;
        for (l, &on) in lanes.iter().enumerate() {
            m |= u16::from(on) << l;
        }
        Mask(m)
    }

    /// The mask as one bool per lane (for selects over all lanes).
    #[inline]
    pub fn to_lanes(self) -> [bool; LANES] {
        std::array::from_fn(|l| self.0 >> l & 1 == 1)
    }

    pub fn get(self, lane: usize) -> bool {
        self.0 >> lane & 1 == 1
    }

    pub fn count(self) -> u32 {
        self.0.count_ones()
    }

    pub fn any(self) -> bool {
        self.0 != 0
    }

    pub fn and(self, o: Mask) -> Mask {
        Mask(self.0 & o.0)
    }

    pub fn and_not(self, o: Mask) -> Mask {
        Mask(self.0 & !o.0)
    }

    /// Active lanes, lowest first (one step per active lane: the next set bit).
    #[inline]
    pub fn lanes(self) -> impl Iterator<Item = usize> {
        let mut bits = self.0;
        std::iter::from_fn(move || {
            (bits != 0).then(|| {
                let l = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                l
            })
        })
    }
}

/// Identifies an instrumented buffer (see [`super::buffer`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct BufferId(pub u16);

/// What a kernel tells the modelled machine it executes. All addresses are modelled byte
/// addresses (see [`super::buffer::Memory`]).
pub trait Probe {
    /// Whether this probe records anything; kernels may skip bookkeeping when it does not.
    const ENABLED: bool;
    /// `n` vector instructions (arithmetic, compares, selects, mask operations) under `mask`.
    fn vector(&mut self, n: u32, mask: Mask);
    /// `n` scalar instructions (loop control, per-primitive setup done one at a time).
    fn scalar(&mut self, n: u32);
    /// A contiguous load of `bytes` at `addr` (a vector load when `bytes` > 4).
    fn read(&mut self, buf: BufferId, addr: u64, bytes: u32);
    /// A contiguous store of `bytes` at `addr`.
    fn write(&mut self, buf: BufferId, addr: u64, bytes: u32);
    /// A gather: each active lane loads `bytes` at its own address.
    fn gather(&mut self, buf: BufferId, addrs: &Lanes<u64>, bytes: u32, mask: Mask);
    /// A scatter: each active lane stores `bytes` at its own address.
    fn scatter(&mut self, buf: BufferId, addrs: &Lanes<u64>, bytes: u32, mask: Mask);
    /// An atomic read-modify-write of `bytes` at `addr`.
    fn atomic(&mut self, buf: BufferId, addr: u64, bytes: u32);
}

/// The probe of `cpu-native`: records nothing, costs nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoProbe;

impl Probe for NoProbe {
    const ENABLED: bool = false;
    #[inline(always)]
    fn vector(&mut self, _: u32, _: Mask) {}
    #[inline(always)]
    fn scalar(&mut self, _: u32) {}
    #[inline(always)]
    fn read(&mut self, _: BufferId, _: u64, _: u32) {}
    #[inline(always)]
    fn write(&mut self, _: BufferId, _: u64, _: u32) {}
    #[inline(always)]
    fn gather(&mut self, _: BufferId, _: &Lanes<u64>, _: u32, _: Mask) {}
    #[inline(always)]
    fn scatter(&mut self, _: BufferId, _: &Lanes<u64>, _: u32, _: Mask) {}
    #[inline(always)]
    fn atomic(&mut self, _: BufferId, _: u64, _: u32) {}
}

/// The distinct cache lines (of `line_bytes`) the active lanes of a gather or scatter touch, in
/// first-touch order. This is what a gather costs on the modelled machine.
pub fn distinct_lines(addrs: &Lanes<u64>, bytes: u32, mask: Mask, line_bytes: u32) -> Vec<u64> {
    let mut lines: Vec<u64> = Vec::with_capacity(LANES);
    let shift = line_bytes.trailing_zeros();
    for l in mask.lanes() {
        let first = addrs[l] >> shift;
        let last = (addrs[l] + u64::from(bytes.max(1)) - 1) >> shift;
        for line in first..=last {
            if !lines.contains(&line) {
                lines.push(line);
            }
        }
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masks_count_and_iterate_lanes() {
        let m = Mask::from_fn(|l| l % 3 == 0);
        assert_eq!(m.count(), 6);
        assert_eq!(m.lanes().collect::<Vec<_>>(), vec![0, 3, 6, 9, 12, 15]);
        assert_eq!(Mask::first(5).count(), 5);
        assert_eq!(Mask::first(16), Mask::ALL);
        assert_eq!(Mask::ALL.and_not(m).count(), 10);
        let lanes = m.to_lanes();
        assert_eq!(lanes.iter().filter(|&&b| b).count(), 6);
        assert!(lanes[0] && lanes[15] && !lanes[1]);
        assert_eq!(Mask::from_lanes(&lanes), m);
    }

    #[test]
    fn a_gather_spanning_a_line_boundary_touches_both_lines() {
        let mut addrs = [0u64; LANES];
        addrs[0] = 62;
        assert_eq!(distinct_lines(&addrs, 4, Mask::first(1), 64), vec![0, 1]);
    }
}
