//! Where a traversal keeps the far children it still has to visit: no stack (kd-restart), a
//! short ring buffer that drops its oldest entry when full, or a full stack (a ring buffer as
//! deep as the deepest tree, so it never drops). Generic over the entry: one ray's interval
//! (`Entry`) or a packet's four intervals and lane mask (`packet::PacketEntry`).
use super::MAX_DEPTH;

/// A far child of one ray and the part of the ray's interval inside it.
#[derive(Copy, Clone, Default)]
pub struct Entry {
    /// Index of the far child.
    pub node: u32,
    /// Start of the ray's interval inside it.
    pub t0: f32,
    /// End of the ray's interval inside it.
    pub t1: f32,
}

/// Where a traversal keeps far children to visit later (`NoStack`, `ShortStack`, `FullStack`).
pub trait Stack<E> {
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
