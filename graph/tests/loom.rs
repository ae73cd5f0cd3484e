//! Model check (loom) of the scheduler's token protocol: the very `protocol.rs` the engine
//! runs, compiled here against loom's atomics, on a 3-node chain and on a 1-parent /
//! 2-child fan-out, over four chunks (two in flight, slots reused while a reader may
//! still be on them) and two threads. Loom explores the interleavings (bounded
//! preemptions) and fails on a data race on a slot, a lost wake-up (work left undone), or
//! a wrong value. A third graph has a feedback edge (the MOC feeding the filterbank
//! below it: the target reads its source's previous chunk). The engine's ready set, the
//! caller's wait and the parking of idle threads are checked by `tests/loom_wakeup.rs`.
//!
//! No thread spins (loom cannot explore spin loops): the source is a node like the
//! others, READY while chunks remain and its slot is free, and every thread runs ready
//! nodes until the ready set is empty, then stops. Whoever makes a node READY offers
//! it, so if the protocol never loses a wake-up, all work gets done.

#![allow(dead_code, unsafe_code)]

mod sync {
    pub(crate) use loom::sync::atomic::{fence, AtomicBool, AtomicU32, AtomicU64, Ordering};
}

#[path = "../src/protocol.rs"]
mod protocol;

mod model;

use loom::cell::UnsafeCell;
use loom::sync::atomic::{AtomicU64, Ordering};
use loom::sync::Arc;
use protocol::{next_chunk, release, try_claim, Links, NodeSync};

struct Model {
    sync: Vec<NodeSync>,
    links: Vec<Links>,
    slots: Vec<[UnsafeCell<u64>; 2]>,
    ready: AtomicU64,
    chunks: u64,
}

impl Model {
    fn new(parents: &[&[usize]], feedback: &[(usize, usize)], chunks: u64) -> Self {
        let n = parents.len();
        let links = model::links_with_feedback(parents, feedback, false);
        let sync: Vec<NodeSync> = (0..n).map(|_| NodeSync::new()).collect();
        // as `Engine::install`: slot 1 stands for chunk −1 of a feedback source (value 0)
        for (s, l) in sync.iter().zip(&links) {
            s.readers_left[1].store(l.feedback_to.len() as u32, Ordering::Relaxed);
        }
        Model {
            sync,
            links,
            slots: (0..n)
                .map(|_| [UnsafeCell::new(0), UnsafeCell::new(0)])
                .collect(),
            ready: AtomicU64::new(0),
            chunks,
        }
    }

    fn offer(&self, n: usize) {
        let budget_left = n != 0 || next_chunk(&self.sync, 0) < self.chunks;
        if budget_left && try_claim(&self.sync, &self.links, n) {
            if n == 0 && next_chunk(&self.sync, 0) >= self.chunks {
                // the claim raced with the last chunk: give it back untouched
                self.sync[0].claimed.store(false, Ordering::Release);
                return;
            }
            self.ready.fetch_or(1 << n, Ordering::AcqRel);
        }
    }

    /// What node `n` must hold for chunk `k` (see [`model::expected`]).
    fn expected(&self, n: usize, k: u64) -> u64 {
        model::expected(&self.links, n, k)
    }

    /// Process + Release of a claimed node (the source publishes k + 1).
    fn run(&self, n: usize) {
        let k = next_chunk(&self.sync, n);
        let slot = (k % 2) as usize;
        // SAFETY (checked by loom): parents' slots are published and pinned, ours is free.
        let value = if n == 0 {
            k + 1
        } else {
            self.links[n]
                .parents
                .iter()
                .map(|&p| self.slots[p][slot].with(|v| unsafe { *v }))
                .chain(
                    self.links[n]
                        .feedback_from
                        .iter()
                        .map(|&s| self.slots[s][1 - slot].with(|v| unsafe { *v })),
                )
                .sum::<u64>()
                + n as u64
        };
        self.slots[n][slot].with_mut(|v| unsafe { *v = value });
        release(&self.sync, &self.links, n, k, |x| self.offer(x));
    }

    /// Runs ready nodes until there are none.
    fn drain(&self) {
        loop {
            let bits = self.ready.load(Ordering::Acquire);
            if bits == 0 {
                return;
            }
            let b = bits.trailing_zeros() as usize;
            if self.ready.fetch_and(!(1 << b), Ordering::AcqRel) & (1 << b) != 0 {
                self.run(b);
            }
        }
    }
}

/// Threads besides the main one (which also runs nodes).
const WORKERS: usize = 1;
/// Chunks through the graph: the 4th reuses the slot of the 2nd, which a reader may still
/// have been consuming concurrently (the WAIT state).
const CHUNKS: u64 = 4;

fn check(parents: &'static [&'static [usize]]) {
    check_with_feedback(parents, &[]);
}

fn check_with_feedback(parents: &'static [&'static [usize]], feedback: &'static [(usize, usize)]) {
    check_bounded(parents, feedback, 2);
}

/// The split model's preemption bound: 1 (3 s) unless `AFE_LOOM_FULL` is set (not empty,
/// not `0`), which gives the full search of the other models, 2 (minutes; docs/
/// architecture.md gives the command): CI runs the bounded one.
fn split_bound() -> usize {
    match std::env::var("AFE_LOOM_FULL") {
        Ok(v) if !v.is_empty() && v != "0" => 2,
        _ => 1,
    }
}

fn check_bounded(
    parents: &'static [&'static [usize]],
    feedback: &'static [(usize, usize)],
    preemptions: usize,
) {
    let mut builder = loom::model::Builder::new();
    builder.preemption_bound = Some(preemptions);
    builder.check(move || {
        let m = Arc::new(Model::new(parents, feedback, CHUNKS));
        m.offer(0);
        let workers: Vec<_> = (0..WORKERS)
            .map(|_| {
                let m = Arc::clone(&m);
                loom::thread::spawn(move || m.drain())
            })
            .collect();
        m.drain();
        for w in workers {
            w.join().expect("worker");
        }
        m.drain();
        for (n, s) in m.sync.iter().enumerate() {
            assert_eq!(
                s.produced.load(Ordering::Acquire),
                m.chunks,
                "node {n}: work lost"
            );
        }
        let last = m.chunks - 1;
        for n in 0..parents.len() {
            let got = m.slots[n][(last % 2) as usize].with(|v| unsafe { *v });
            assert_eq!(got, m.expected(n, last), "node {n}");
            let prev = m.slots[n][((last - 1) % 2) as usize].with(|v| unsafe { *v });
            assert_eq!(prev, m.expected(n, last - 1), "node {n}, chunk before");
        }
    });
}

/// input → a → b
#[test]
fn chain_of_three() {
    check(&[&[], &[0], &[1]]);
}

/// input → a → {b, c}
#[test]
fn fan_out_to_two_children() {
    check(&[&[], &[0], &[1], &[1]]);
}

/// A node split into two parts, as the engine lays it out: input → a → {part 0, part 1}
/// (table entries after the node), and the node joining both parts beside its own input.
#[test]
fn split_node_joins_its_parts() {
    check_bounded(&[&[], &[0], &[1, 3, 4], &[1], &[1]], &[], split_bound());
}

/// input → a → b → c, with c feeding a back: a's chunk k waits for c's chunk k − 1, and
/// c's slot of chunk k − 1 stays pinned until a has read it.
#[test]
fn feedback_edge_to_a_lower_node() {
    check_with_feedback(&[&[], &[0], &[1], &[2]], &[(3, 1)]);
}
