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
//! Not cached: buffers, textures, bind groups and query sets. Their sizes and contents follow
//! the frame (geometry, image, map resolution), so each run makes its own; a pool reusing
//! them across runs is not built.

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
}

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

    /// Starts a run's setup account.
    pub fn begin_run(&self) {
        let mut inner = self.lock();
        inner.created_in_run.clear();
        inner.setup = Setup::default();
    }

    /// Ends a run's account and returns it; when the run failed (`ok` false) the objects it
    /// created are dropped.
    pub fn end_run(&self, ok: bool) -> Setup {
        let mut inner = self.lock();
        let created = std::mem::take(&mut inner.created_in_run);
        if !ok {
            for key in &created {
                inner.objects.remove(key);
            }
        }
        std::mem::take(&mut inner.setup)
    }
}
