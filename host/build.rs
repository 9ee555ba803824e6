use spirv_builder::{SpirvBuilder, SpirvMetadata};
fn main() {
    // Read at run time: a build script compiled once may run for a checkout elsewhere.
    let manifest = std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let dir = std::path::Path::new(&manifest).join("../shader-crate");
    let mut b = SpirvBuilder::new(dir, "spirv-unknown-vulkan1.2");
    b.build_script.defaults = true;
    b.build_script.env_shader_spv_path = Some(true);
    // Keep the names of variables: the host matches its kernels' buffers to bindings by name.
    b.spirv_metadata = SpirvMetadata::NameVariables;
    b.build().expect("shader crate failed to compile to SPIR-V");
}
