//! A run's wall-clock budget (`--run-timeout`, a scenario's `run_timeout_s`), enforced
//! cooperatively: the executions call [`Deadline::check`] at safe points (before each task of a
//! machine step, per row of the reference, between GPU submissions), and past the deadline the
//! run unwinds with a [`Cancelled`] payload that the harness turns into a failed run. Unwinding
//! ([`std::panic::resume_unwind`], which does not run the panic hook and prints nothing) frees
//! everything the run allocated on the way out, on every thread rayon gave it.

use std::time::{Duration, Instant};

/// When a run must stop; the default never expires.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Deadline(Option<(Instant, Duration)>);

/// The unwind payload of a run stopped at its deadline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cancelled {
    /// The budget the run had.
    pub limit: Duration,
}

impl Deadline {
    /// A deadline `limit` from now.
    pub fn after(limit: Duration) -> Deadline {
        Deadline(Some((Instant::now() + limit, limit)))
    }

    /// The time since the deadline was set ([`Duration::ZERO`] for the default one).
    pub fn elapsed(&self) -> Duration {
        self.0.map_or(Duration::ZERO, |(at, limit)| {
            (Instant::now() + limit).saturating_duration_since(at)
        })
    }

    /// Whether the deadline has passed.
    pub fn expired(&self) -> bool {
        self.0.is_some_and(|(at, _)| Instant::now() >= at)
    }

    /// Stops the run (unwinds with [`Cancelled`]) when the deadline has passed.
    pub fn check(&self) {
        if let Some((at, limit)) = self.0 {
            if Instant::now() >= at {
                std::panic::resume_unwind(Box::new(Cancelled { limit }));
            }
        }
    }
}

/// The [`Cancelled`] in a caught unwind payload, if it is one.
pub fn cancelled(payload: &(dyn std::any::Any + Send)) -> Option<Cancelled> {
    payload.downcast_ref::<Cancelled>().copied()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_passed_deadline_unwinds_with_its_limit_and_no_deadline_never_does() {
        Deadline::default().check();
        let d = Deadline::after(Duration::ZERO);
        assert!(d.expired());
        let caught = std::panic::catch_unwind(|| d.check()).unwrap_err();
        assert_eq!(
            cancelled(caught.as_ref()),
            Some(Cancelled {
                limit: Duration::ZERO
            })
        );
        Deadline::after(Duration::from_secs(3600)).check();
    }
}
