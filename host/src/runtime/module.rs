//! The SPIR-V module built from `shader-crate/` and what it declares: every entry point's
//! name, workgroup size, bindings (by name, with element size and read-only flag) and
//! push-constant size, read from the module itself (`reflect`). Both runtimes check every pass
//! against it (`validate`): a host declaration that does not match its shader is an error
//! naming the kernel and the binding, never a wrong binding.
use super::{reflect, Access, Bind, Kernel};
use crate::error::{bail, err, Result};
use kdray_shared::parts::SPLIT_BINDINGS;

static SPIRV: &[u8] = include_bytes!("../../kernels/kdray.spv");

/// Environment variable naming a SPIR-V file to use instead of the built-in module: for kernel
/// development (a module built by `scripts/kernels.sh` from edited sources runs without
/// rebuilding the host). Its entry points are reflected and checked like the built-in ones.
pub const SPIRV_OVERRIDE: &str = "KDRAY_SPIRV";

/// The module's bytes: the file `KDRAY_SPIRV` names, else the built-in module.
fn spirv_bytes() -> Result<&'static [u8]> {
    static B: std::sync::OnceLock<Result<Vec<u8>, String>> = std::sync::OnceLock::new();
    match std::env::var_os(SPIRV_OVERRIDE) {
        None => Ok(SPIRV),
        Some(path) => B
            .get_or_init(|| std::fs::read(&path).map_err(|e| format!("{SPIRV_OVERRIDE}={}: {e}", path.to_string_lossy())))
            .as_ref()
            .map(|v| v.as_slice())
            .map_err(|e| err!(Gpu: "{e}")),
    }
}

/// The words of the SPIR-V module built from `shader-crate/`, without its source-line
/// instructions (`OpLine`, `OpNoLine`: debug information only; the build keeps variable names,
/// which leaves `OpNoLine`s behind, and the module is then word for word what a build without
/// names gives, apart from the names).
pub fn spirv_words() -> Result<Vec<u32>> {
    const OP_LINE: u32 = 8;
    const OP_NO_LINE: u32 = 317;
    let words: Vec<u32> = spirv_bytes()?.chunks_exact(4).map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]])).collect();
    let mut out = Vec::with_capacity(words.len());
    out.extend_from_slice(&words[..words.len().min(5)]);
    let mut i = 5;
    while i < words.len() {
        let n = (words[i] >> 16) as usize;
        if n == 0 || i + n > words.len() {
            // Malformed: leave the rest as it is (reflection reports it).
            out.extend_from_slice(&words[i..]);
            break;
        }
        let op = words[i] & 0xffff;
        if op != OP_LINE && op != OP_NO_LINE {
            out.extend_from_slice(&words[i..i + n]);
        }
        i += n;
    }
    Ok(out)
}

/// How the scene's splittable arrays are bound in a pass: one split code per entry of
/// `kdray_shared::parts::SPLIT_BINDINGS` (0: bound whole), taken from the pass's bindings.
pub type Splits = [u32; SPLIT_BINDINGS.len()];

/// The splits of a pass's bindings (`Bind::split` of the arrays `SPLIT_BINDINGS` names).
pub fn splits(host: &[Bind]) -> Splits {
    let mut s = [0; SPLIT_BINDINGS.len()];
    for (k, names) in SPLIT_BINDINGS.iter().enumerate() {
        if let Some(b) = host.iter().find(|b| b.name == names[0]) {
            s[k] = b.split;
        }
    }
    s
}

/// `words` with every specialization constant whose `SpecId` is k (the ids of
/// `SPLIT_BINDINGS`) defaulting to `splits[k]`: a driver given no specialization takes the
/// defaults, so a pipeline made from these words is specialized (wgpu passes no
/// specialization info for SPIR-V passthrough).
pub fn specialize(words: &[u32], splits: &Splits) -> Vec<u32> {
    const OP_DECORATE: u32 = 71;
    const DECORATION_SPEC_ID: u32 = 1;
    const OP_SPEC_CONSTANT: u32 = 50;
    let mut ids = std::collections::HashMap::new();
    let mut out = words.to_vec();
    for pass in 0..2 {
        let mut i = 5;
        while i < out.len() {
            let n = (out[i] >> 16) as usize;
            if n == 0 || i + n > out.len() {
                break;
            }
            let op = out[i] & 0xffff;
            if pass == 0 && op == OP_DECORATE && n == 4 && out[i + 2] == DECORATION_SPEC_ID {
                ids.insert(out[i + 1], out[i + 3]);
            }
            // OpSpecConstant: result type, result id, one literal word (32-bit types).
            if pass == 1 && op == OP_SPEC_CONSTANT && n == 4 {
                if let Some(&k) = ids.get(&out[i + 2]) {
                    if let Some(&v) = splits.get(k as usize) {
                        out[i + 3] = v;
                    }
                }
            }
            i += n;
        }
    }
    out
}

/// The module's entry points as reflected (parsed once).
pub fn module_info() -> Result<&'static reflect::Module> {
    static M: std::sync::OnceLock<Result<reflect::Module, String>> = std::sync::OnceLock::new();
    M.get_or_init(|| spirv_words().and_then(|w| reflect::parse(&w)).map_err(|e| format!("{e:#}")))
        .as_ref()
        .map_err(|e| err!(Gpu: "the SPIR-V module cannot be read: {e}"))
}

/// The entry point a kernel names: `family::name` in the module (rust-gpu qualifies entry
/// points by their module), found by its full name or, when unique, by its last segment.
pub fn find_entry<'m>(m: &'m reflect::Module, name: &str) -> Option<&'m reflect::EntryPoint> {
    m.entry_point(name).or_else(|| {
        let suffix = format!("::{name}");
        let mut it = m.entry_points.iter().filter(|e| e.name.ends_with(&suffix));
        match (it.next(), it.next()) {
            (Some(e), None) => Some(e),
            _ => None,
        }
    })
}

/// The short name of an entry point (without its module path).
pub fn short_name(full: &str) -> &str {
    full.rsplit("::").next().unwrap_or(full)
}

/// Where an entry point's binding comes from.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Slot {
    /// The host binding of this index.
    Host(usize),
    /// The kernel's parameters (`Kernel::params`), which the runtime puts in a small buffer:
    /// for entry points that take them as a storage buffer named `params` rather than as
    /// push constants.
    Params,
}

/// The name of the binding that carries a kernel's parameters when they are not push constants.
pub const PARAMS: &str = "params";

/// Checks a pass against what its entry point declares in the module: parameter size (push
/// constants, or the `params` buffer), workgroup size, and each binding, matched by name, for
/// element size and access; that no buffer is bound twice where one binding writes it; and that
/// the module declares only storage buffers in set 0 with names (the build keeps them). Returns
/// where each binding of the entry point comes from. Both runtimes call this, so a wrong
/// declaration fails natively too (in CI without a GPU), naming the kernel and the binding.
pub fn validate(k: &dyn Kernel, host: &[Bind], info: &reflect::EntryPoint) -> Result<Vec<Slot>> {
    let name = k.entry();
    check_aliasing(k, host)?;
    for b in &info.bindings {
        if b.name.is_none() || b.set != 0 || b.kind != reflect::BindingKind::StorageBuffer {
            bail!(Gpu: "kernel {name}: binding {} (set {}) must be a named storage buffer in set 0 (the module was not built by scripts/kernels.sh?)", b.binding, b.set);
        }
    }
    let params = k.params().len() as u32;
    let params_binding = info.bindings.iter().find(|b| b.name.as_deref() == Some(PARAMS) && !host.iter().any(|h| h.name == PARAMS));
    let declared = match params_binding {
        Some(b) => b.element_size.unwrap_or(0),
        None => info.push_constant_size,
    };
    if params != declared {
        bail!(Gpu: "kernel {name}: the host passes {params} bytes of parameters, the shader declares {declared}");
    }
    let draw = k.draw();
    if draw.is_some() != (info.stage == reflect::Stage::Vertex) {
        bail!(Gpu: "kernel {name}: the host {} but the entry point is a {:?} shader", if draw.is_some() { "draws" } else { "dispatches" }, info.stage);
    }
    if draw.is_none() && (k.workgroup() != info.workgroup_size[0] || info.workgroup_size[1] != 1 || info.workgroup_size[2] != 1) {
        bail!(Gpu: "kernel {name}: the host dispatches workgroups of {}, the shader declares {:?}", k.workgroup(), info.workgroup_size);
    }
    let mut order = Vec::with_capacity(info.bindings.len());
    for b in &info.bindings {
        let bn = b.name.as_deref().unwrap_or_default();
        if params_binding.is_some_and(|p| p.binding == b.binding) {
            if !b.read_only {
                bail!(Gpu: "kernel {name}: its parameter buffer must be read-only");
            }
            order.push(Slot::Params);
            continue;
        }
        let i = host.iter().position(|h| h.name == bn).ok_or_else(|| err!(Gpu: "kernel {name}: binding '{bn}' ({}) is not supplied by the host", b.binding))?;
        let h = &host[i];
        if let Some(e) = b.element_size {
            if e != h.elem {
                bail!(Gpu: "kernel {name}: binding '{}' holds elements of {e} bytes in the shader, {} on the host", h.name, h.elem);
            }
        }
        match (h.access, b.read_only) {
            (Access::Read, false) => bail!(Gpu: "kernel {name}: binding '{}' is written by the shader but bound for reading", h.name),
            (Access::Write, true) => bail!(Gpu: "kernel {name}: binding '{}' is read-only in the shader but bound for writing", h.name),
            _ => {}
        }
        order.push(Slot::Host(i));
    }
    // An array bound in parts must be read by the entry point in parts: it declares every part
    // (a kernel that takes the array whole would read only the first).
    let declares = |n: &str| info.bindings.iter().any(|b| b.name.as_deref() == Some(n));
    if let Some(h) = host.iter().find(|h| h.split != 0 && SPLIT_BINDINGS.iter().any(|p| p[0] == h.name && declares(p[0]) && !declares(p[1]))) {
        bail!(Gpu: "kernel {name}: '{}' is split across bindings (a scene larger than one storage buffer), but the kernel does not read it in parts", h.name);
    }
    // A host binding the entry point does not declare is one the shader does not use (rust-gpu
    // drops unused parameters, e.g. the kd-tree arrays of the brute-force kernels): allowed for
    // reading, an error for writing (the host would expect results that never come).
    // A drawing pass's target is written by the image copy, not bound to the shaders.
    let target = draw.map(|d| d.target);
    if let Some(extra) = host.iter().find(|h| h.access == Access::Write && Some(h.name) != target && !info.bindings.iter().any(|b| b.name.as_deref() == Some(h.name))) {
        bail!(Gpu: "kernel {name}: the host binds '{}' for writing but the shader has no such binding", extra.name);
    }
    Ok(order)
}

/// Fails if a pass names a binding twice, or binds one buffer twice where one binding writes it.
pub fn check_aliasing(k: &dyn Kernel, host: &[Bind]) -> Result<()> {
    for (i, x) in host.iter().enumerate() {
        for y in &host[i + 1..] {
            if x.name == y.name {
                bail!(Gpu: "kernel {}: binding '{}' is given twice", k.entry(), x.name);
            }
            if x.buffer.id() == y.buffer.id() && (x.access == Access::Write || y.access == Access::Write) {
                bail!(Gpu: "kernel {}: buffer '{}' is bound as both '{}' and '{}' and written", k.entry(), x.buffer.label(), x.name, y.name);
            }
        }
    }
    Ok(())
}

/// Checks a pass natively against the module's entry point of the same name (see `validate`).
/// A kernel the module does not carry passes: the native runtime instantiates more variants of
/// a family than the module does (short stacks of 1..=8 entries, the module a few), and those
/// share their declaration with the family's other members, which are checked.
pub fn check_kernel(k: &dyn Kernel) -> Result<()> {
    let m = module_info()?;
    match find_entry(m, &k.entry()) {
        Some(info) => validate(k, &k.bindings(), info).map(|_| ()),
        None => check_aliasing(k, &k.bindings()),
    }
}

