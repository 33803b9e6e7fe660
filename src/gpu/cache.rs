//! The device's objects made once and reused by every run of a process: shader modules,
//! bind-group and pipeline layouts, compute and render pipelines. A sweep's second run of an
//! algorithm finds them here instead of compiling its WGSL and pipelines again, which on a
//! software driver (lavapipe compiles every pipeline with LLVM) costs far more than the frame.
//!
//! Each object is keyed by everything that determines it: a module by its WGSL text (as
//! [`super::pass::Program`] joins it), a bind-group layout by its stages and binding kinds, a
//! pipeline layout by its groups' keys, a pipeline by its program's key, entry points, override
//! constants and fixed-function state (vertex input, primitive, depth, colour target). Labels
//! are not part of a key: two algorithms declaring the same layout share it, under the label of
//! the first.
//!
//! Creating an object that is not here is the run's *GPU setup*: its host time is reported
//! apart from the run's time ([`Setup`], `gpu_setup_ms` of the record), since a sweep pays it
//! once. An object created during a run that fails (a validation error, a lost device, a
//! cancelled run) is dropped again, so a later run never reuses an object a failed run made.
//! The cache belongs to its device: a lost device's objects go with it.
//!
//! Where the backend offers `PIPELINE_CACHE` (Vulkan), every pipeline is also created through
//! one [`wgpu::PipelineCache`] kept in memory (never written to disk), so the driver may share
//! compiled stages between pipelines (a timed pipeline and its counting twin share their vertex
//! stage).
//!
//! Buffers ([`Cache::take_buffer`]): the storage, uniform and vertex buffers a run makes through
//! [`super::Gpu::upload`] and [`super::Gpu::storage_buffer`] go back to a pool when the run ends
//! well, and a later run asking for a buffer of the same size and usage gets one of them
//! (filled with its data, or zeroed, by queue writes that precede the run's next submission)
//! instead of a new allocation: the runs of a sweep whose frame keeps its sizes (image, map resolution) reuse
//! their eye, map and count buffers. Only exact sizes are reused, since a shader's
//! `arrayLength` reads a bound buffer's size. The pool holds the last run's buffers only (those
//! a run does not take are dropped), so it never holds more than one run's working set; a
//! failed run's buffers are dropped. Outside a run (a test holding a device) nothing is pooled.
//!
//! Not reused: textures (their contents would have to be cleared by format), bind groups, query
//! sets and the host-readable staging buffers.

use std::any::Any;
use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Instant;

/// What a run spent on GPU setup: acquiring the device (after a device loss; the first device
/// of a process is acquired before the sweep) and creating the objects it did not find in the
/// cache, in host milliseconds, and how many objects it created and reused.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Setup {
    /// Host time acquiring a device during the run (0 when the device was already there).
    pub device_ms: f64,
    /// Host time creating shader modules, layouts and pipelines.
    pub objects_ms: f64,
    /// Objects created (modules, layouts, pipelines).
    pub created: u32,
    /// Objects found in the cache.
    pub reused: u32,
    /// Whether the pipelines went through the driver's pipeline cache ([`Cache::driver`]).
    pub driver_cache: bool,
    /// Buffers allocated, and taken from the pool instead, by the run.
    pub buffers_made: u32,
    pub buffers_reused: u32,
}

impl Setup {
    /// The run's whole GPU setup time, milliseconds.
    pub fn ms(&self) -> f64 {
        self.device_ms + self.objects_ms
    }

    /// The record's `execution.gpu_setup` entry.
    pub fn to_json(self) -> serde_json::Value {
        serde_json::json!({
            "device_ms": self.device_ms,
            "objects_ms": self.objects_ms,
            "objects_created": self.created,
            "objects_reused": self.reused,
            "driver_pipeline_cache": self.driver_cache,
            "buffers_made": self.buffers_made,
            "buffers_reused": self.buffers_reused,
        })
    }
}

/// The kinds of object the cache holds (part of each key).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    Module,
    BindGroupLayout,
    PipelineLayout,
    ComputePipeline,
    RenderPipeline,
}

#[derive(Default)]
struct Inner {
    objects: HashMap<(Kind, String), Box<dyn Any + Send + Sync>>,
    /// Keys created since the run began, dropped if it fails.
    created_in_run: Vec<(Kind, String)>,
    setup: Setup,
    /// Whether a run is under way (buffers are pooled only then).
    in_run: bool,
    /// Buffers of the last run that ended well, by size and usage.
    free: HashMap<BufferKey, Vec<wgpu::Buffer>>,
    /// Buffers the current run made or took.
    lent: Vec<(BufferKey, wgpu::Buffer)>,
}

/// A pooled buffer's size (bytes) and usage.
pub type BufferKey = (u64, wgpu::BufferUsages);

/// The cache of one device.
pub struct Cache {
    inner: Mutex<Inner>,
    /// wgpu's pipeline cache, where the backend offers one (in memory only).
    pub driver: Option<wgpu::PipelineCache>,
}

impl Cache {
    pub fn new(driver: Option<wgpu::PipelineCache>) -> Cache {
        Cache {
            inner: Mutex::new(Inner::default()),
            driver,
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The object of `kind` under `key`: the cached one, or `create`'s, timed into the run's
    /// setup and kept.
    pub fn get<T: Clone + Send + Sync + 'static>(
        &self,
        kind: Kind,
        key: String,
        create: impl FnOnce() -> T,
    ) -> T {
        let mut inner = self.lock();
        let key = (kind, key);
        if let Some(found) = inner.objects.get(&key).and_then(|o| o.downcast_ref::<T>()) {
            let found = found.clone();
            inner.setup.reused += 1;
            return found;
        }
        let start = Instant::now();
        let made = create();
        inner.setup.objects_ms += start.elapsed().as_secs_f64() * 1e3;
        inner.setup.created += 1;
        inner.created_in_run.push(key.clone());
        inner.objects.insert(key, Box::new(made.clone()));
        made
    }

    /// Host milliseconds the current run has spent creating objects so far, for an
    /// execution that times its own setup and leaves this part out of it.
    pub fn run_objects_ms(&self) -> f64 {
        self.lock().setup.objects_ms
    }

    /// A buffer of `key` for the current run and whether it came from the pool: `(buffer, true)`
    /// holds the last user's contents, which the caller overwrites; `(make(), false)` is new.
    /// Outside a run, `make`'s, not pooled.
    pub fn take_buffer(
        &self,
        key: BufferKey,
        make: impl FnOnce() -> wgpu::Buffer,
    ) -> (wgpu::Buffer, bool) {
        let mut inner = self.lock();
        if !inner.in_run {
            return (make(), false);
        }
        let found = inner.free.get_mut(&key).and_then(Vec::pop);
        let reused = found.is_some();
        let buffer = found.unwrap_or_else(make);
        match reused {
            true => inner.setup.buffers_reused += 1,
            false => inner.setup.buffers_made += 1,
        }
        inner.lent.push((key, buffer.clone()));
        (buffer, reused)
    }

    /// Starts a run's setup account.
    pub fn begin_run(&self) {
        let mut inner = self.lock();
        inner.created_in_run.clear();
        inner.setup = Setup::default();
        inner.lent.clear();
        inner.in_run = true;
    }

    /// Ends a run's account and returns it; when the run failed (`ok` false) the objects and
    /// buffers it created are dropped, else its buffers become the pool.
    pub fn end_run(&self, ok: bool) -> Setup {
        let mut inner = self.lock();
        let created = std::mem::take(&mut inner.created_in_run);
        if !ok {
            for key in &created {
                inner.objects.remove(key);
            }
        }
        let lent = std::mem::take(&mut inner.lent);
        inner.free.clear();
        if ok {
            for (key, buffer) in lent {
                inner.free.entry(key).or_default().push(buffer);
            }
        }
        inner.in_run = false;
        std::mem::take(&mut inner.setup)
    }
}
