//! Minimal SPIR-V reflection: reads the module built from `shader-crate/` (rust-gpu, SPIR-V 1.5)
//! and returns, per compute, vertex or fragment entry point, its stage, workgroup size, the descriptor bindings it uses
//! (set, binding, buffer kind, read-only-ness, element size, debug name) and its push-constant
//! size. The host validates its typed kernel bindings against what the shader module declares,
//! so a mismatch (a kernel edited on one side only) is an error naming the kernel, never a
//! wrong binding at dispatch time.
//!
//! Scope: only what rust-gpu emits. From SPIR-V 1.4 on, an entry point's interface list names
//! every global variable it statically uses, so its bindings are exactly the interface variables
//! with a `Binding` decoration (rust-gpu shares variables across entry points; only those in the
//! interface count). For an older module (header version < 1.4) every variable of the
//! StorageBuffer, Uniform or PushConstant class is attributed to every entry point.
//! Malformed input is an error, never a panic or an endless loop.
use crate::error::{bail, ensure, err, Context, Result};
use std::collections::{BTreeMap, HashMap, HashSet};

/// A parsed SPIR-V module: what its compute, vertex and fragment entry points declare.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Module {
    /// The GLCompute, Kernel, Vertex and Fragment entry points, in the module's order (other
    /// execution models are skipped).
    pub entry_points: Vec<EntryPoint>,
}

/// The pipeline stage an entry point runs in (its execution model).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Stage {
    /// GLCompute or Kernel: a compute pass's kernel.
    Compute,
    /// A vertex shader (a drawing pass's `Kernel::entry`).
    Vertex,
    /// A fragment shader.
    Fragment,
}

/// One entry point and the resources it uses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EntryPoint {
    /// The name in `OpEntryPoint` (rust-gpu qualifies it by its module: `family::name`).
    pub name: String,
    /// Compute, vertex or fragment.
    pub stage: Stage,
    /// `OpExecutionMode LocalSize` (or `OpExecutionModeId LocalSizeId` of plain `OpConstant`s);
    /// zeros for vertex and fragment shaders.
    pub workgroup_size: [u32; 3],
    /// Descriptor bindings used by this entry point, sorted by (set, binding).
    pub bindings: Vec<Binding>,
    /// Size in bytes of the push-constant block used by this entry point (0 if none).
    pub push_constant_size: u32,
}

/// What a descriptor binding holds.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum BindingKind {
    /// A variable of the `StorageBuffer` class, or a `BufferBlock` struct in the `Uniform` class.
    StorageBuffer,
    /// A `Block` struct in the `Uniform` class.
    UniformBuffer,
    /// Images, samplers, anything else with a `Binding` decoration.
    Other,
}

/// One descriptor binding of an entry point.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Binding {
    /// `DescriptorSet` decoration (0 if none).
    pub set: u32,
    /// `Binding` decoration.
    pub binding: u32,
    /// What the binding holds.
    pub kind: BindingKind,
    /// `NonWritable` on the variable, or on every member of its block struct; uniform buffers
    /// are always read-only.
    pub read_only: bool,
    /// Buffers only: the `ArrayStride` of the block's trailing runtime array (`&[T]`), or the
    /// size of the block's single sized member (`&T`); None otherwise.
    pub element_size: Option<u32>,
    /// Whether `element_size` is the stride of a trailing runtime array.
    pub runtime_array: bool,
    /// `OpName` of the variable, if the module carries debug names.
    pub name: Option<String>,
}

impl Module {
    /// The entry point with exactly this name, if any.
    pub fn entry_point(&self, name: &str) -> Option<&EntryPoint> {
        self.entry_points.iter().find(|e| e.name == name)
    }
}

const MAGIC: u32 = 0x0723_0203;
const NONE: u32 = u32::MAX; // "no member" in the decoration key
// Storage classes.
const SC_UNIFORM: u32 = 2;
const SC_PUSH_CONSTANT: u32 = 9;
const SC_STORAGE_BUFFER: u32 = 12;
// Decorations.
const D_BLOCK: u32 = 2;
const D_BUFFER_BLOCK: u32 = 3;
const D_ARRAY_STRIDE: u32 = 6;
const D_NON_WRITABLE: u32 = 24;
const D_BINDING: u32 = 33;
const D_DESCRIPTOR_SET: u32 = 34;
const D_OFFSET: u32 = 35;

enum Ty {
    Scalar(u32),
    /// Vector or matrix: component / column type and count.
    Repeat(u32, u32),
    Array(u32, u32),
    RuntimeArray(u32),
    Struct(Vec<u32>),
    Pointer(u32),
}

enum LocalSize {
    Literal([u32; 3]),
    Ids([u32; 3]),
}

#[derive(Default)]
struct Raw {
    names: HashMap<u32, String>,
    /// (target, member or NONE, decoration) -> first literal operand (0 if none).
    decos: HashMap<(u32, u32, u32), u32>,
    types: HashMap<u32, Ty>,
    consts: HashMap<u32, u32>,
    /// variable -> (pointer type, storage class)
    vars: BTreeMap<u32, (u32, u32)>,
}

/// A nul-terminated UTF-8 literal and the number of words it takes.
fn string(words: &[u32]) -> Result<(String, usize)> {
    let mut bytes = Vec::new();
    for (i, w) in words.iter().enumerate() {
        for b in w.to_le_bytes() {
            if b == 0 {
                let s = String::from_utf8(bytes).map_err(|_| err!(Gpu: "malformed SPIR-V: literal string is not UTF-8"))?;
                return Ok((s, i + 1));
            }
            bytes.push(b);
        }
    }
    bail!(Gpu: "malformed SPIR-V: literal string without a nul terminator")
}

/// Reads a SPIR-V module given as words in host byte order. Malformed input, a wrong or
/// byte-swapped magic number, or a compute entry point without a resolvable workgroup size
/// is an error.
pub fn parse(words: &[u32]) -> Result<Module> {
    ensure!(words.len() >= 5, Gpu: "not a SPIR-V module: {} words, the header alone is 5", words.len());
    match words[0] {
        MAGIC => {}
        m if m.swap_bytes() == MAGIC => bail!(Gpu: "byte-swapped SPIR-V (magic {m:#010x}): words must be in host order"),
        m => bail!(Gpu: "not a SPIR-V module: magic {m:#010x}, expected {MAGIC:#010x}"),
    }
    let modern = words[1] >= 0x0001_0400;
    let mut r = Raw::default();
    let mut entries = Vec::new(); // (execution model, function, name, interface)
    let mut local = HashMap::new();
    let mut at = 5;
    while at < words.len() {
        let (count, op) = ((words[at] >> 16) as usize, words[at] & 0xffff);
        ensure!(count != 0, Gpu: "malformed SPIR-V: zero word count (opcode {op}) at word {at}");
        let ops = words.get(at + 1..at + count).ok_or_else(|| {
            err!(Gpu: "malformed SPIR-V: instruction (opcode {op}) at word {at} runs past the end of the module")
        })?;
        let w = |i: usize| {
            ops.get(i).copied().ok_or_else(|| err!(Gpu: "malformed SPIR-V: opcode {op} at word {at} has too few operands"))
        };
        match op {
            5 => drop(r.names.insert(w(0)?, string(&ops[1..])?.0)),
            15 => {
                let (name, used) = string(ops.get(2..).unwrap_or(&[]))?;
                entries.push((w(0)?, w(1)?, name, ops[2 + used..].to_vec()));
            }
            16 if w(1)? == 17 => drop(local.insert(w(0)?, LocalSize::Literal([w(2)?, w(3)?, w(4)?]))),
            331 if w(1)? == 38 => drop(local.insert(w(0)?, LocalSize::Ids([w(2)?, w(3)?, w(4)?]))),
            71 => drop(r.decos.insert((w(0)?, NONE, w(1)?), w(2).unwrap_or(0))),
            72 => drop(r.decos.insert((w(0)?, w(1)?, w(2)?), w(3).unwrap_or(0))),
            20 => drop(r.types.insert(w(0)?, Ty::Scalar(4))),
            21 | 22 => drop(r.types.insert(w(0)?, Ty::Scalar(w(1)? / 8))),
            23 | 24 => drop(r.types.insert(w(0)?, Ty::Repeat(w(1)?, w(2)?))),
            28 => drop(r.types.insert(w(0)?, Ty::Array(w(1)?, w(2)?))),
            29 => drop(r.types.insert(w(0)?, Ty::RuntimeArray(w(1)?))),
            30 => drop(r.types.insert(w(0)?, Ty::Struct(ops[1..].to_vec()))),
            32 => drop(r.types.insert(w(0)?, Ty::Pointer(w(2)?))),
            43 => drop(r.consts.insert(w(1)?, w(2)?)),
            59 => drop(r.vars.insert(w(1)?, (w(0)?, w(2)?))),
            _ => {}
        }
        at += count;
    }

    let mut entry_points = Vec::new();
    for (model, function, name, interface) in entries {
        let stage = match model {
            0 => Stage::Vertex,
            4 => Stage::Fragment,
            5 | 6 => Stage::Compute,
            _ => continue, // GLCompute, Kernel, Vertex and Fragment only
        };
        let workgroup_size = match local.get(&function) {
            _ if stage != Stage::Compute => [0; 3],
            Some(LocalSize::Literal(s)) => *s,
            Some(LocalSize::Ids(ids)) => {
                let c = |id: u32| r.consts.get(&id).copied();
                match (c(ids[0]), c(ids[1]), c(ids[2])) {
                    (Some(x), Some(y), Some(z)) => [x, y, z],
                    _ => bail!(Gpu: "entry point `{name}`: LocalSizeId operands are not plain OpConstants"),
                }
            }
            None => bail!(Gpu: "entry point `{name}` has no LocalSize execution mode"),
        };
        let vars: Vec<u32> = if modern {
            let mut seen = HashSet::new();
            interface.into_iter().filter(|v| r.vars.contains_key(v) && seen.insert(*v)).collect()
        } else {
            let classes = [SC_UNIFORM, SC_PUSH_CONSTANT, SC_STORAGE_BUFFER];
            r.vars.iter().filter(|(_, (_, c))| classes.contains(c)).map(|(v, _)| *v).collect()
        };
        let (mut bindings, mut push_constant_size) = (Vec::new(), 0);
        for var in vars {
            let (ptr, class) = r.vars[&var];
            let what = || match r.names.get(&var) {
                Some(n) => format!("entry point `{name}`, variable `{n}` (%{var})"),
                None => format!("entry point `{name}`, variable %{var}"),
            };
            let Some(Ty::Pointer(pointee)) = r.types.get(&ptr) else {
                bail!(Gpu: "{}: type %{ptr} is not a pointer", what());
            };
            if class == SC_PUSH_CONSTANT {
                let size = r.size(*pointee, 0).with_context(|| format!("{}: push-constant block", what()))?;
                push_constant_size = push_constant_size.max(size);
            } else if let Some(binding) = r.decos.get(&(var, NONE, D_BINDING)) {
                bindings.push(r.binding(var, class, *pointee, *binding).with_context(what)?);
            } else if class == SC_STORAGE_BUFFER || class == SC_UNIFORM {
                bail!(Gpu: "{}: buffer without a Binding decoration", what());
            }
        }
        bindings.sort_by_key(|b| (b.set, b.binding));
        entry_points.push(EntryPoint { name, stage, workgroup_size, bindings, push_constant_size });
    }
    Ok(Module { entry_points })
}

impl Raw {
    fn has(&self, id: u32, member: u32, deco: u32) -> bool {
        self.decos.contains_key(&(id, member, deco))
    }

    fn binding(&self, var: u32, class: u32, pointee: u32, binding: u32) -> Result<Binding> {
        // An array of descriptors: the block is its element.
        let block = match self.types.get(&pointee) {
            Some(Ty::Array(e, _) | Ty::RuntimeArray(e)) => *e,
            _ => pointee,
        };
        let members = match self.types.get(&block) {
            Some(Ty::Struct(m)) => Some(m.as_slice()),
            _ => None,
        };
        let kind = match (class, members.is_some()) {
            (SC_STORAGE_BUFFER, _) => BindingKind::StorageBuffer,
            (SC_UNIFORM, true) if self.has(block, NONE, D_BUFFER_BLOCK) => BindingKind::StorageBuffer,
            (SC_UNIFORM, true) if self.has(block, NONE, D_BLOCK) => BindingKind::UniformBuffer,
            _ => BindingKind::Other,
        };
        let read_only = kind == BindingKind::UniformBuffer
            || self.has(var, NONE, D_NON_WRITABLE)
            || members.is_some_and(|m| {
                !m.is_empty() && (0..m.len() as u32).all(|i| self.has(block, i, D_NON_WRITABLE))
            });
        let (element_size, runtime_array) = match members {
            _ if kind == BindingKind::Other => (None, false),
            Some([.., last]) if matches!(self.types.get(last), Some(Ty::RuntimeArray(_))) => {
                let Some(Ty::RuntimeArray(e)) = self.types.get(last) else { unreachable!() };
                (Some(self.stride(*last, *e, 0)?), true)
            }
            Some([only]) => (Some(self.size(*only, 0)?), false),
            _ => (None, false),
        };
        Ok(Binding {
            set: self.decos.get(&(var, NONE, D_DESCRIPTOR_SET)).copied().unwrap_or(0),
            binding,
            kind,
            read_only,
            element_size,
            runtime_array,
            name: self.names.get(&var).cloned(),
        })
    }

    /// Element stride of an array type: its `ArrayStride`, else the element's size.
    fn stride(&self, array: u32, elem: u32, depth: u32) -> Result<u32> {
        match self.decos.get(&(array, NONE, D_ARRAY_STRIDE)) {
            Some(s) => Ok(*s),
            None => self.size(elem, depth + 1),
        }
    }

    /// Byte size of a type; a runtime array counts as 0, a struct ends at its furthest member.
    fn size(&self, ty: u32, depth: u32) -> Result<u32> {
        ensure!(depth < 64, Gpu: "type %{ty} is nested too deeply (cyclic?)");
        let n = match self.types.get(&ty) {
            Some(Ty::Scalar(b)) => Some(*b),
            Some(Ty::Repeat(c, n)) => self.size(*c, depth + 1)?.checked_mul(*n),
            Some(Ty::Array(e, len)) => {
                let Some(len) = self.consts.get(len) else { bail!(Gpu: "array length %{len} is not an OpConstant") };
                self.stride(ty, *e, depth)?.checked_mul(*len)
            }
            Some(Ty::RuntimeArray(_)) => Some(0),
            Some(Ty::Struct(members)) => {
                let mut end = Some(0u32);
                for (i, m) in members.iter().enumerate() {
                    let Some(e) = end else { break };
                    let offset = self.decos.get(&(ty, i as u32, D_OFFSET)).copied().unwrap_or(e);
                    end = offset.checked_add(self.size(*m, depth + 1)?).map(|x| x.max(e));
                }
                end
            }
            _ => bail!(Gpu: "type %{ty} has no known size"),
        };
        n.ok_or_else(|| err!(Gpu: "size of type %{ty} overflows u32"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn str_words(s: &str) -> Vec<u32> {
        let mut b = s.as_bytes().to_vec();
        b.resize((b.len() / 4 + 1) * 4, 0);
        b.chunks(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
    }

    struct Asm(Vec<u32>);
    impl Asm {
        fn op(&mut self, op: u32, args: &[u32]) -> &mut Self {
            self.0.push(((args.len() as u32 + 1) << 16) | op);
            self.0.extend_from_slice(args);
            self
        }
        fn op_s(&mut self, op: u32, pre: &[u32], s: &str, post: &[u32]) -> &mut Self {
            self.op(op, &[pre, &str_words(s), post].concat())
        }
    }

    /// Entry `a` (64x1x1) uses rays (0,1; NonWritable variable), params (0,0; NonWritable
    /// members) and a push-constant block; entry `b` (LocalSizeId 3x2x1) uses params, out (0,2;
    /// writable) and a uniform buffer (1,0).
    fn sample(version: u32) -> Vec<u32> {
        let mut a = Asm(vec![MAGIC, version, 0, 200, 0]);
        a.op_s(15, &[5, 100], "a", &[13, 23, 42]).op_s(15, &[5, 101], "b", &[33, 23, 52, 60]);
        a.op(16, &[100, 17, 64, 1, 1]).op(331, &[101, 38, 4, 5, 6]);
        a.op_s(5, &[13], "rays", &[]).op_s(5, &[23], "params", &[]);
        for (var, set, binding) in [(13, 0, 1), (23, 0, 0), (33, 0, 2), (52, 1, 0)] {
            a.op(71, &[var, 34, set]).op(71, &[var, 33, binding]);
        }
        a.op(71, &[13, 24]).op(72, &[21, 0, 24]).op(72, &[20, 0, 24]).op(72, &[20, 1, 24]);
        a.op(71, &[10, 6, 16]).op(71, &[30, 6, 4]).op(71, &[44, 6, 4]);
        for s in [11, 21, 31, 40, 50] {
            a.op(71, &[s, 2]).op(72, &[s, 0, 35, 0]);
        }
        a.op(72, &[20, 1, 35, 16]).op(72, &[40, 1, 35, 4]).op(72, &[40, 2, 35, 8]);
        a.op(21, &[1, 32, 0]).op(22, &[2, 32]).op(23, &[3, 2, 4]);
        a.op(43, &[1, 4, 3]).op(43, &[1, 5, 2]).op(43, &[1, 6, 1]);
        a.op(29, &[10, 3]).op(30, &[11, 10]).op(32, &[12, 12, 11]).op(59, &[12, 13, 12]);
        a.op(30, &[20, 1, 3]).op(30, &[21, 20]).op(32, &[22, 12, 21]).op(59, &[22, 23, 12]);
        a.op(29, &[30, 1]).op(30, &[31, 30]).op(32, &[32, 12, 31]).op(59, &[32, 33, 12]);
        a.op(28, &[44, 2, 4]).op(30, &[40, 1, 2, 44]).op(32, &[41, 9, 40]).op(59, &[41, 42, 9]);
        a.op(30, &[50, 3]).op(32, &[51, 2, 50]).op(59, &[51, 52, 2]);
        a.op(32, &[61, 1, 1]).op(59, &[61, 60, 1]); // an Input variable: not a binding
        a.0
    }

    fn buffer(set: u32, binding: u32, ro: bool, size: u32, rt: bool, name: Option<&str>) -> Binding {
        let kind = BindingKind::StorageBuffer;
        let name = name.map(String::from);
        Binding { set, binding, kind, read_only: ro, element_size: Some(size), runtime_array: rt, name }
    }

    #[test]
    fn two_entry_points() {
        let m = parse(&sample(0x0001_0500)).unwrap();
        let a = m.entry_point("a").unwrap();
        assert_eq!((a.stage, a.workgroup_size), (Stage::Compute, [64, 1, 1]));
        assert_eq!(a.push_constant_size, 20); // offset 8 + 3 x stride 4
        assert_eq!(a.bindings, [buffer(0, 0, true, 32, false, Some("params")), buffer(0, 1, true, 16, true, Some("rays"))]);
        let b = m.entry_point("b").unwrap();
        assert_eq!(b.workgroup_size, [3, 2, 1]);
        assert_eq!(b.push_constant_size, 0);
        let uniform = Binding { kind: BindingKind::UniformBuffer, ..buffer(1, 0, true, 16, false, None) };
        assert_eq!(b.bindings, [buffer(0, 0, true, 32, false, Some("params")), buffer(0, 2, false, 4, true, None), uniform]);
        assert!(m.entry_point("c").is_none());
    }

    #[test]
    fn vertex_and_fragment_shaders_have_stages_and_no_workgroup() {
        let mut a = Asm(sample(0x0001_0500));
        a.op_s(15, &[0, 102], "v", &[13]).op_s(15, &[4, 103], "f", &[]).op_s(15, &[3, 104], "g", &[]);
        let m = parse(&a.0).unwrap();
        let v = m.entry_point("v").unwrap();
        assert_eq!((v.stage, v.workgroup_size), (Stage::Vertex, [0; 3]));
        assert_eq!(v.bindings, [buffer(0, 1, true, 16, true, Some("rays"))]);
        assert_eq!(m.entry_point("f").unwrap().stage, Stage::Fragment);
        assert!(m.entry_point("g").is_none(), "geometry shaders are skipped");
    }

    #[test]
    fn old_spirv_uses_all_variables() {
        let m = parse(&sample(0x0001_0300)).unwrap();
        for e in &m.entry_points {
            let bindings: Vec<_> = e.bindings.iter().map(|b| (b.set, b.binding)).collect();
            assert_eq!(bindings, [(0, 0), (0, 1), (0, 2), (1, 0)]);
            assert_eq!(e.push_constant_size, 20);
        }
    }

    #[test]
    fn malformed_is_an_error() {
        let good = sample(0x0001_0500);
        let mut zero = good.clone();
        zero.push(0);
        let mut cyclic = Asm(good.clone());
        cyclic.op(30, &[90, 90]).op(32, &[91, 9, 90]).op(59, &[91, 92, 9]).op_s(15, &[5, 100], "c", &[92]);
        let mut unterminated = good[..5].to_vec();
        unterminated.extend([(3 << 16) | 5, 1, u32::from_le_bytes(*b"abcd")]);
        let swapped: Vec<u32> = good.iter().map(|w| w.swap_bytes()).collect();
        let mut bad_magic = good.clone();
        bad_magic[0] = 0x1234_5678;
        let cases = [&good[..good.len() - 1], &good[..3], &zero, &cyclic.0, &unterminated, &swapped, &bad_magic];
        for words in cases {
            assert!(parse(words).is_err());
        }
        assert!(format!("{:#}", parse(&cyclic.0).unwrap_err()).contains("entry point `c`"));
        // No panic on any truncation or any single corrupted word.
        for i in 0..good.len() {
            let _ = parse(&good[..i]);
            for v in [0, 1, 0xffff, 0x1_0000, u32::MAX] {
                let mut w = good.clone();
                w[i] = v;
                let _ = parse(&w);
            }
        }
    }
}
