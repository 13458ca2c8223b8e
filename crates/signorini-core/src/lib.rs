//! Numerical core of Signorini: linear and nonlinear mechanical models with unilateral
//! contacts, event-capturing time integrators with exact discrete energy bookkeeping, LCP
//! solvers, and nonsmooth modal analysis.
//!
//! Pure computation: no async, no files, no network, no printing. A run reports through an
//! [`observer::Observer`]; the service decides where the records go.
#![warn(missing_docs)]

pub(crate) mod anderson;
pub mod band;
pub mod banded_contact;
pub mod capabilities;
pub mod checkpoint;
pub mod contact;
pub mod contact_region;
pub(crate) mod dense;
pub mod energy;
pub mod expr;
pub mod friction;
pub mod integrators;
pub mod job;
pub mod lagrangian;
pub mod lcp;
pub mod modal;
pub mod model;
pub mod nonlinear;
pub mod observer;
pub mod outcome;
pub mod rigid;
pub mod scenes;
pub mod soi2;
pub mod spec;
pub mod stepping;
pub mod study;
pub mod trace;
pub mod triplets;
pub mod wfem;
