//! Compiles `proto/signorini/v1/*.proto` without a system protoc: `protox` parses them into a
//! file-descriptor set, `tonic-prost-build` generates the messages and the gRPC service into OUT_DIR.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let files = [
        "proto/signorini/v1/spec.proto",
        "proto/signorini/v1/service.proto",
    ];
    for f in &files {
        println!("cargo:rerun-if-changed={f}");
    }
    let fds = protox::compile(files, ["proto"])?;
    tonic_prost_build::configure().compile_fds(fds)?;
    Ok(())
}
