//! Whether the store takes writes. A write the store refuses for want of room (SQLite's
//! `SQLITE_FULL`, PostgreSQL's SQLSTATE class 53) or because it became read-only marks the store
//! degraded, with the store's reason; it stays so until a probe ([`Backend::probe_write`]) of
//! one chunk of a series succeeds. While degraded, `/healthz` answers 503 with the reason and
//! new submissions are refused naming it.
//!
//! [`Backend::probe_write`]: super::Backend::probe_write

use super::StoreError;
use std::sync::Mutex;

/// The store's health: `None` while it takes writes, else why it does not.
#[derive(Debug, Default)]
pub struct Health {
    refused: Mutex<Option<String>>,
}

impl Health {
    /// Why the store does not take writes now, if it does not.
    pub fn refused(&self) -> Option<String> {
        self.lock().clone()
    }

    /// Notes the outcome of a write: a refusal for want of room or a read-only store degrades
    /// the store (other failures say nothing of its room). The outcome is handed back.
    pub fn noted<T>(&self, outcome: Result<T, StoreError>) -> Result<T, StoreError> {
        if let Err(e) = &outcome
            && e.refuses_writes()
        {
            *self.lock() = Some(e.to_string());
        }
        outcome
    }

    /// Records a probe's outcome: healthy after a probe that wrote, degraded with the probe's
    /// failure otherwise (whatever it is: the store could not take the write).
    pub fn probed(&self, outcome: Result<(), StoreError>) -> Option<String> {
        let mut refused = self.lock();
        *refused = outcome.err().map(|e| e.to_string());
        refused.clone()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Option<String>> {
        self.refused.lock().unwrap_or_else(|p| p.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rusqlite::ffi;

    fn sqlite(code: std::os::raw::c_int) -> StoreError {
        StoreError::Sql(rusqlite::Error::SqliteFailure(ffi::Error::new(code), None))
    }

    #[test]
    fn a_full_store_is_degraded_until_a_probe_writes() {
        let health = Health::default();
        assert_eq!(health.refused(), None);
        // A constraint violation says nothing of the store's room.
        let _ = health.noted::<()>(Err(sqlite(ffi::SQLITE_CONSTRAINT)));
        assert_eq!(health.refused(), None);
        let _ = health.noted::<()>(Err(sqlite(ffi::SQLITE_FULL)));
        let reason = health.refused().expect("degraded after SQLITE_FULL");
        assert!(reason.contains("full"), "{reason}");
        // An ordinary write that succeeds does not end it: only a probe does.
        assert!(health.noted(Ok(())).is_ok());
        assert_eq!(health.refused().as_deref(), Some(reason.as_str()));
        assert!(health.probed(Err(sqlite(ffi::SQLITE_READONLY))).is_some());
        assert_eq!(health.probed(Ok(())), None);
        assert_eq!(health.refused(), None);
    }

    #[test]
    fn postgres_out_of_room_or_read_only_refuses_writes() {
        let full = StoreError::PostgresRefused {
            reason: "could not extend file: No space left on device".into(),
            sqlstate: "53100".into(),
        };
        assert!(full.refuses_writes());
        assert!(!StoreError::Postgres("connection reset".into()).refuses_writes());
    }
}
