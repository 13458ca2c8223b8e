//! Protobuf: the generated messages and gRPC service of `proto/signorini/v1` (built into
//! OUT_DIR), and [`encode`], the one protobuf encoding of the engine's domain types that gRPC and
//! zenoh share.

pub mod encode;
pub mod typed_spec;

/// The encoded file-descriptor set of `proto/signorini/v1` (gRPC server reflection).
pub const FILE_DESCRIPTOR_SET: &[u8] = tonic::include_file_descriptor_set!("signorini_descriptor");

/// `signorini.v1`.
#[allow(missing_docs, clippy::all, clippy::pedantic)]
pub mod v1 {
    tonic::include_proto!("signorini.v1");
}
