//! Job ids and the wall clock of the service.

use crate::engine::EngineError;
use signorini_core::spec::SpecError;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

/// Milliseconds since the Unix epoch.
pub fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

/// Nanoseconds since the Unix epoch (the stamp of a computed step).
pub(crate) fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Checks a client-chosen id: 1–64 of `[A-Za-z0-9_-]` (safe in a zenoh key and a URL).
pub fn check_id(id: &str) -> Result<(), EngineError> {
    if id.is_empty()
        || id.len() > 64
        || !id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
    {
        return Err(EngineError::Invalid(SpecError::new(
            "id",
            "1 to 64 characters among A-Z a-z 0-9 _ -",
        )));
    }
    Ok(())
}

/// A fresh id: `j`, the acceptance time in ms (so ids sort by age), and 32 random bits.
pub(crate) fn new_id() -> String {
    use std::hash::{BuildHasher, Hasher};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(now_ns());
    h.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
    format!("j{:011x}{:08x}", now_ms(), h.finish() as u32)
}
