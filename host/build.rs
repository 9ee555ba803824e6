use spirv_builder::SpirvBuilder;
fn main() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shader-crate");
    let mut b = SpirvBuilder::new(dir, "spirv-unknown-vulkan1.2");
    b.build_script.defaults = true;
    b.build_script.env_shader_spv_path = Some(true);
    b.build().expect("shader crate failed to compile to SPIR-V");
}
