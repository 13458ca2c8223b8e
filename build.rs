//! Compiles `proto/signorini/v1/*.proto` without a system protoc: `protox` parses them into a
//! file-descriptor set, `tonic-prost-build` generates the messages and the gRPC service into OUT_DIR,
//! and the encoded set is kept there for gRPC server reflection.

use prost::Message;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let files = [
        "proto/signorini/v1/spec.proto",
        "proto/signorini/v1/service.proto",
    ];
    for f in &files {
        println!("cargo:rerun-if-changed={f}");
    }
    let fds = protox::compile(files, ["proto"])?;
    let out = std::path::PathBuf::from(std::env::var("OUT_DIR")?);
    std::fs::write(out.join("signorini_descriptor.bin"), fds.encode_to_vec())?;
    tonic_prost_build::configure().compile_fds(fds)?;
    Ok(())
}
