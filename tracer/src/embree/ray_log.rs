//! A log of every Embree query, for the throughput benchmark (feature `ray-log`, off by default; the
//! benchmark enables it through a dev-dependency of `tracer` on itself).
//!
//! The benchmark's yardstick for the path tracer's overhead is raw Embree on *the very rays the path tracer
//! cast*: it records them once ([`record`]) and replays them through [`super::TriangleScene`] alone. Random
//! rays from the air are a different workload (they start in empty space, not on the dense mesh where bounce
//! and shadow rays start), so only a replay says which share of the tracer's time is Embree's.
//!
//! Cost when compiled in but not recording: one relaxed atomic load per query. Recording takes a mutex per
//! query and is meant for one-thread runs (the log then keeps the path tracer's own query order).

use glam::Vec3;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

/// One Embree query as the tracer issued it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoggedRay {
    pub org: Vec3,
    pub dir: Vec3,
    pub tnear: f32,
    pub tfar: f32,
    /// `rtcOccluded1` (true) or `rtcIntersect1` (false).
    pub shadow: bool,
}

static RECORDING: AtomicBool = AtomicBool::new(false);
static LOG: Mutex<Vec<LoggedRay>> = Mutex::new(Vec::new());
/// Serialises [`record`] calls, so that two recordings never interleave their rays.
static SESSION: Mutex<()> = Mutex::new(());

/// Appends a query to the log while a [`record`] call is running.
#[inline(always)]
pub(super) fn log(org: Vec3, dir: Vec3, tnear: f32, tfar: f32, shadow: bool) {
    if RECORDING.load(Ordering::Relaxed) {
        push(LoggedRay { org, dir, tnear, tfar, shadow });
    }
}

/// The slow path of [`log`], kept out of line so that the query wrappers stay small.
#[cold]
#[inline(never)]
fn push(ray: LoggedRay) {
    LOG.lock().unwrap_or_else(std::sync::PoisonError::into_inner).push(ray);
}

/// Runs `f` and returns its result with every Embree query made meanwhile, by any thread, in the order the
/// queries were made.
pub fn record<T>(f: impl FnOnce() -> T) -> (T, Vec<LoggedRay>) {
    let _session = SESSION.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    LOG.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clear();
    RECORDING.store(true, Ordering::SeqCst);
    let r = f();
    RECORDING.store(false, Ordering::SeqCst);
    let rays = std::mem::take(&mut *LOG.lock().unwrap_or_else(std::sync::PoisonError::into_inner));
    (r, rays)
}
