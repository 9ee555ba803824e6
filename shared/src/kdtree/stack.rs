//! Where a traversal keeps the far children it still has to visit: no stack (kd-restart), a
//! short ring buffer that drops its oldest entry when full, or a full stack (a ring buffer as
//! deep as the deepest tree, so it never drops). Generic over the entry: one ray's interval
//! (`Entry`) or a packet's four intervals and lane mask (`packet::PacketEntry`).
use super::MAX_DEPTH;

/// No node: an interval that ends at the scene box, not at a split plane.
pub const NO_NODE: u32 = u32::MAX;

/// A far child of one ray and the part of the ray's interval inside it, as a stack keeps it:
/// `Entry` for a full stack (which never restarts), `ExitEntry` where entries may be dropped
/// (a restart needs the plane that ends the interval).
pub trait StackEntry: Copy + Default {
    /// The far child `node`, the interval [`t0`, `t1`] inside it, and the node whose plane ends
    /// it at `t1` (`NO_NODE`: the scene box).
    fn new(node: u32, t0: f32, t1: f32, exit: u32) -> Self;
    /// The far child.
    fn node(&self) -> u32;
    /// Start of the interval.
    fn t0(&self) -> f32;
    /// End of the interval.
    fn t1(&self) -> f32;
    /// The node whose plane ends the interval (`NO_NODE` where not kept).
    fn exit(&self) -> u32;
}

/// A far child of one ray and the part of the ray's interval inside it (12 bytes).
#[derive(Copy, Clone, Default)]
pub struct Entry {
    /// Index of the far child.
    pub node: u32,
    /// Start of the ray's interval inside it.
    pub t0: f32,
    /// End of the ray's interval inside it.
    pub t1: f32,
}

impl StackEntry for Entry {
    #[inline(always)]
    fn new(node: u32, t0: f32, t1: f32, _exit: u32) -> Self {
        Entry { node, t0, t1 }
    }
    #[inline(always)]
    fn node(&self) -> u32 {
        self.node
    }
    #[inline(always)]
    fn t0(&self) -> f32 {
        self.t0
    }
    #[inline(always)]
    fn t1(&self) -> f32 {
        self.t1
    }
    #[inline(always)]
    fn exit(&self) -> u32 {
        NO_NODE
    }
}

/// `Entry` and the node whose split plane ends the interval, for stacks that may drop entries.
#[derive(Copy, Clone, Default)]
pub struct ExitEntry {
    /// The far child and the interval inside it.
    pub e: Entry,
    /// The node whose plane ends the interval at `e.t1` (`NO_NODE`: the scene box).
    pub exit: u32,
}

impl StackEntry for ExitEntry {
    #[inline(always)]
    fn new(node: u32, t0: f32, t1: f32, exit: u32) -> Self {
        ExitEntry { e: Entry { node, t0, t1 }, exit }
    }
    #[inline(always)]
    fn node(&self) -> u32 {
        self.e.node
    }
    #[inline(always)]
    fn t0(&self) -> f32 {
        self.e.t0
    }
    #[inline(always)]
    fn t1(&self) -> f32 {
        self.e.t1
    }
    #[inline(always)]
    fn exit(&self) -> u32 {
        self.exit
    }
}

/// Where a traversal keeps far children to visit later (`NoStack`, `ShortStack`, `FullStack`).
pub trait Stack<E> {
    /// Whether it never drops an entry (a full stack): then a traversal never restarts.
    const KEEPS_ALL: bool;
    /// Empties the stack and resets `dropped`.
    fn clear(&mut self);
    /// Pushes `e`; `NoStack` drops it, a full `ShortStack` drops its oldest entry.
    fn push(&mut self, e: E);
    /// Pops the newest entry; `None` when empty.
    fn pop(&mut self) -> Option<E>;
    /// Whether an entry was lost since the last `clear` (then a restart is needed).
    fn dropped(&self) -> bool;
}

/// No stack: every far child is "dropped" and found again by restarting.
pub struct NoStack {
    dropped: bool,
}
impl NoStack {
    /// An empty stack that has dropped nothing.
    pub fn new() -> Self {
        NoStack { dropped: false }
    }
}
impl Default for NoStack {
    fn default() -> Self {
        Self::new()
    }
}
impl<E> Stack<E> for NoStack {
    const KEEPS_ALL: bool = false;
    #[inline(always)]
    fn clear(&mut self) {
        self.dropped = false;
    }
    #[inline(always)]
    fn push(&mut self, _e: E) {
        self.dropped = true;
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<E> {
        None
    }
    #[inline(always)]
    fn dropped(&self) -> bool {
        self.dropped
    }
}

/// A ring buffer of N entries: pushing onto a full stack overwrites the oldest entry.
pub struct ShortStack<E, const N: usize> {
    items: [E; N],
    top: usize,
    len: usize,
    dropped: bool,
}
impl<E: Copy + Default, const N: usize> ShortStack<E, N> {
    /// An empty stack that has dropped nothing.
    pub fn new() -> Self {
        ShortStack { items: [E::default(); N], top: 0, len: 0, dropped: false }
    }
}
impl<E: Copy + Default, const N: usize> Default for ShortStack<E, N> {
    fn default() -> Self {
        Self::new()
    }
}
impl<E: Copy, const N: usize> Stack<E> for ShortStack<E, N> {
    const KEEPS_ALL: bool = N >= MAX_DEPTH;
    #[inline(always)]
    fn clear(&mut self) {
        self.len = 0;
        self.dropped = false;
    }
    #[inline(always)]
    fn push(&mut self, e: E) {
        self.items[self.top] = e;
        self.top = if self.top + 1 == N { 0 } else { self.top + 1 };
        if self.len == N {
            self.dropped = true;
        } else {
            self.len += 1;
        }
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<E> {
        if self.len == 0 {
            return None;
        }
        self.top = if self.top == 0 { N - 1 } else { self.top - 1 };
        self.len -= 1;
        Some(self.items[self.top])
    }
    #[inline(always)]
    fn dropped(&self) -> bool {
        self.dropped
    }
}

/// The classic full stack of one ray: deep enough for any tree the builder makes.
pub type FullStack = ShortStack<Entry, MAX_DEPTH>;
