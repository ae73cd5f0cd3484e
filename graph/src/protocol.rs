//! The token protocol of the concurrent scheduler: Ready → Process → Wait → Release over
//! two output slots per node (the design of ARCHITECTURE.md, "The scheduler").
//!
//! Chunk `k` of a node is written to slot `k % 2`. A node may process chunk `k` (READY)
//! when every parent has published chunk `k` (`produced > k`) and every reader of its own
//! slot `k % 2` has finished with chunk `k − 2` (`readers_left == 0`: the AFE's Wait state,
//! folded into READY by the double buffering). RELEASE publishes the slot (`produced = k+1`,
//! `readers_left = readers`), hands a "consumed" token back to each parent, and offers
//! the children, the parents and the node itself to the scheduler.
//!
//! A feedback edge (the MOC feeding the filterbank below it) runs the other way: the
//! target reads its source's chunk `k − 1` before processing chunk `k`. READY for the
//! target's chunk `k` then also needs the source's `produced ≥ k`; the target counts among
//! the source's readers and hands its token for chunk `k − 1` back at its RELEASE of chunk
//! `k` (for `k = 0`, the token of a "chunk −1" slot the table is built with), and the
//! source's RELEASE offers the target.
//!
//! Memory-ordering rules: publish with Release and check with Acquire; `fetch_sub`
//! returns the previous value (last reader: `== 1`); a claim is re-validated after it is
//! taken (TOCTOU); `try_claim` starts with a SeqCst fence, because each caller has just
//! changed one condition and reads the others (store-buffering pattern).

use crate::sync::{fence, AtomicBool, AtomicU32, AtomicU64, Ordering};

/// Per-node synchronisation state.
#[derive(Debug)]
pub(crate) struct NodeSync {
    /// Number of chunks published (chunk `k` is readable iff `produced > k`).
    pub produced: AtomicU64,
    /// Readers still using each slot.
    pub readers_left: [AtomicU32; 2],
    /// Held by whoever is about to run, or is running, the node.
    pub claimed: AtomicBool,
}

impl NodeSync {
    /// Nothing published, both slots free, unclaimed.
    pub(crate) fn new() -> Self {
        NodeSync {
            produced: AtomicU64::new(0),
            readers_left: [AtomicU32::new(0), AtomicU32::new(0)],
            claimed: AtomicBool::new(false),
        }
    }
}

/// The static links of a node.
#[derive(Debug, Clone, Default)]
pub(crate) struct Links {
    /// Distinct parent nodes.
    pub parents: Box<[usize]>,
    /// Distinct child nodes.
    pub children: Box<[usize]>,
    /// Number of readers of each published slot: children and feedback targets, plus
    /// one when the caller collects this node's output.
    pub readers: u32,
    /// Nodes whose feedback this node takes (their previous chunk).
    pub feedback_from: Box<[usize]>,
    /// Nodes that take this node's feedback.
    pub feedback_to: Box<[usize]>,
}

/// READY for the node's next chunk: parents have it (feedback sources the chunk before),
/// the slot to write is free.
pub(crate) fn is_ready(nodes: &[NodeSync], links: &[Links], n: usize) -> bool {
    let k = nodes[n].produced.load(Ordering::Acquire);
    if nodes[n].readers_left[(k % 2) as usize].load(Ordering::Acquire) != 0 {
        return false;
    }
    links[n]
        .parents
        .iter()
        .all(|&p| nodes[p].produced.load(Ordering::Acquire) > k)
        && links[n]
            .feedback_from
            .iter()
            .all(|&s| nodes[s].produced.load(Ordering::Acquire) >= k)
}

/// Claims node `n` if it is READY and unclaimed. On `true` the caller owns the node until
/// it calls [`release`]. Never loses a wake-up: if the node becomes ready while a claim
/// is being given back, the retry sees it.
pub(crate) fn try_claim(nodes: &[NodeSync], links: &[Links], n: usize) -> bool {
    loop {
        fence(Ordering::SeqCst);
        if nodes[n].claimed.load(Ordering::Acquire) || !is_ready(nodes, links, n) {
            return false;
        }
        if nodes[n]
            .claimed
            .compare_exchange(false, true, Ordering::AcqRel, Ordering::Acquire)
            .is_err()
        {
            return false;
        }
        if is_ready(nodes, links, n) {
            return true;
        }
        nodes[n].claimed.store(false, Ordering::Release);
    }
}

/// The chunk the claim holder of `n` is to process.
pub(crate) fn next_chunk(nodes: &[NodeSync], n: usize) -> u64 {
    nodes[n].produced.load(Ordering::Acquire)
}

/// RELEASE of chunk `k` by the claim holder of `n`: publishes it, returns the parents'
/// tokens and gives up the claim. `offer` is called for every node that may have become
/// ready (parents whose slot became free, children, and `n` itself).
pub(crate) fn release(
    nodes: &[NodeSync],
    links: &[Links],
    n: usize,
    k: u64,
    mut offer: impl FnMut(usize),
) {
    let slot = (k % 2) as usize;
    nodes[n].readers_left[slot].store(links[n].readers, Ordering::Relaxed);
    nodes[n].produced.store(k + 1, Ordering::Release);
    for &p in links[n].parents.iter() {
        consumed(nodes, p, k, &mut offer);
    }
    for &s in links[n].feedback_from.iter() {
        // the source's chunk k − 1, in the slot of parity k + 1
        consumed(nodes, s, k + 1, &mut offer);
    }
    for &c in links[n].children.iter().chain(links[n].feedback_to.iter()) {
        offer(c);
    }
    nodes[n].claimed.store(false, Ordering::Release);
    offer(n);
}

/// A reader of node `p` is done with its chunk `k`; offers `p` when it was the last one.
pub(crate) fn consumed(nodes: &[NodeSync], p: usize, k: u64, mut offer: impl FnMut(usize)) {
    if nodes[p].readers_left[(k % 2) as usize].fetch_sub(1, Ordering::AcqRel) == 1 {
        offer(p);
    }
}
