//! The Signorini binary's library: job-spec files, output writers, the CLI, and the service.
//! The numerics live in `signorini-core`; this crate only moves data in and out.

pub mod cli;
pub mod config;
pub mod engine;
pub mod error;
pub mod lifecycle;
pub mod output;
pub mod problem_file;
pub mod proto;
pub mod server;
pub mod spec_file;
pub mod status;
pub mod store;
pub mod stream;
pub mod study;
pub mod vtk;

/// The system's allocator, counting what each job's run holds (`engine::memory`).
#[global_allocator]
static ALLOCATOR: engine::memory::CountingAllocator = engine::memory::CountingAllocator;
