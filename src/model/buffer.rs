//! Instrumented buffers: every buffer an algorithm uses has a name and a modelled address range,
//! and every access goes through a [`Probe`], which counts reads and writes per buffer and (in
//! the model) runs them through the core's caches.

use super::simd::{BufferId, Lanes, Mask, Probe, LANES};

/// The modelled address space: hands out page-aligned, non-overlapping ranges and remembers the
/// name of each buffer.
#[derive(Clone, Debug)]
pub struct Memory {
    names: Vec<String>,
    next: u64,
}

/// Alignment of buffer base addresses (a 4 KiB page).
const PAGE: u64 = 4096;

impl Default for Memory {
    fn default() -> Self {
        Memory {
            names: Vec::new(),
            next: PAGE,
        }
    }
}

impl Memory {
    /// Reserves `bytes` of modelled memory named `name`; returns its id and base address.
    pub fn reserve(&mut self, name: &str, bytes: u64) -> (BufferId, u64) {
        let id = BufferId(u16::try_from(self.names.len()).expect("fewer than 65536 buffers"));
        self.names.push(name.to_string());
        let base = self.next;
        self.next = (base + bytes.max(1)).div_ceil(PAGE) * PAGE;
        (id, base)
    }

    /// A buffer named `name` holding `data`.
    pub fn buffer<T: Copy>(&mut self, name: &str, data: Vec<T>) -> Buffer<T> {
        Buffer::at(
            self.reserve(name, size_of_val(data.as_slice()) as u64),
            data,
        )
    }

    /// A buffer named `name` of `len` elements of `T` that the host does not hold: its tasks
    /// return their values and the executor places them, so only its modelled accesses
    /// ([`Buffer::record_store`], [`Buffer::record_load`]) are used.
    pub fn unbacked<T: Copy>(&mut self, name: &str, len: usize) -> Buffer<T> {
        Buffer::at(
            self.reserve(name, (len * size_of::<T>()) as u64),
            Vec::new(),
        )
    }

    /// A buffer named `name` over `data` the host already holds (a frame's G-buffer): the
    /// modelled machine reads it where it lies, so the host makes no copy of it either.
    pub fn borrowed<'a, T: Copy>(&mut self, name: &str, data: &'a [T]) -> Buffer<T, &'a [T]> {
        Buffer::at(self.reserve(name, size_of_val(data) as u64), data)
    }

    pub fn name(&self, id: BufferId) -> &str {
        &self.names[id.0 as usize]
    }

    pub fn len(&self) -> usize {
        self.names.len()
    }

    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }
}

/// An array in modelled memory: host data (owned, or borrowed with [`Memory::borrowed`]) plus
/// the id and base address the probe sees.
#[derive(Clone, Debug)]
pub struct Buffer<T, D = Vec<T>> {
    pub id: BufferId,
    pub base: u64,
    pub data: D,
    element: std::marker::PhantomData<T>,
}

impl<T, D> Buffer<T, D> {
    /// `data` at the modelled range `(id, base)` from [`Memory::reserve`].
    pub fn at((id, base): (BufferId, u64), data: D) -> Buffer<T, D> {
        Buffer {
            id,
            base,
            data,
            element: std::marker::PhantomData,
        }
    }
}

impl<T: Copy + Default, D: AsRef<[T]>> Buffer<T, D> {
    pub const ELEMENT: u32 = size_of::<T>() as u32;

    pub fn addr(&self, i: usize) -> u64 {
        self.base + (i * size_of::<T>()) as u64
    }

    /// A scalar load of element `i`.
    #[inline]
    pub fn load<P: Probe>(&self, p: &mut P, i: usize) -> T {
        p.read(self.id, self.addr(i), Self::ELEMENT);
        self.data.as_ref()[i]
    }

    /// A contiguous load of `n` elements from `i` (counted as one access).
    #[inline]
    pub fn load_run<P: Probe>(&self, p: &mut P, i: usize, n: usize) -> &[T] {
        p.read(self.id, self.addr(i), Self::ELEMENT * n as u32);
        &self.data.as_ref()[i..i + n]
    }

    /// A gather of elements `idx` on the active lanes; inactive lanes read as `T::default()`.
    #[inline]
    pub fn gather<P: Probe>(&self, p: &mut P, idx: &Lanes<u32>, mask: Mask) -> Lanes<T> {
        if P::ENABLED {
            let addrs: Lanes<u64> = std::array::from_fn(|l| self.addr(idx[l] as usize));
            p.gather(self.id, &addrs, Self::ELEMENT, mask);
        }
        let data = self.data.as_ref();
        let mut out = [T::default(); LANES];
        for l in mask.lanes() {
            out[l] = data[idx[l] as usize];
        }
        out
    }

    /// Records a contiguous store of `n` elements at `i` without changing host data (for
    /// results a task returns and the executor places, see [`super::Machine::run_phase`]).
    #[inline]
    pub fn record_store<P: Probe>(&self, p: &mut P, i: usize, n: usize) {
        p.write(self.id, self.addr(i), Self::ELEMENT * n as u32);
    }

    /// Records a contiguous load of `n` elements at `i` whose data the task holds locally.
    #[inline]
    pub fn record_load<P: Probe>(&self, p: &mut P, i: usize, n: usize) {
        p.read(self.id, self.addr(i), Self::ELEMENT * n as u32);
    }
}
