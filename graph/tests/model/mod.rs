//! What the loom models share: the graph's links, as `Engine::install` makes them, and the
//! value each node must hold for a chunk.

use crate::protocol::Links;

/// The links of the graph of `parents` (node 0 is the source); with `caller_reads`, every
/// node but the source has the caller as an extra reader, as in the engine.
pub fn links(parents: &[&[usize]], caller_reads: bool) -> Vec<Links> {
    links_with_feedback(parents, &[], caller_reads)
}

/// As [`links`], with feedback edges `(source, target)`: the target takes the source's
/// previous chunk, and counts among the source's readers.
pub fn links_with_feedback(
    parents: &[&[usize]],
    feedback: &[(usize, usize)],
    caller_reads: bool,
) -> Vec<Links> {
    let n = parents.len();
    let mut children = vec![Vec::new(); n];
    for (i, ps) in parents.iter().enumerate() {
        for &p in ps.iter() {
            children[p].push(i);
        }
    }
    let from =
        |i: usize| -> Vec<usize> { feedback.iter().filter(|e| e.1 == i).map(|e| e.0).collect() };
    let to =
        |i: usize| -> Vec<usize> { feedback.iter().filter(|e| e.0 == i).map(|e| e.1).collect() };
    (0..n)
        .map(|i| Links {
            parents: parents[i].to_vec().into(),
            children: children[i].clone().into(),
            readers: (children[i].len() + to(i).len()) as u32 + u32::from(caller_reads && i != 0),
            feedback_from: from(i).into(),
            feedback_to: to(i).into(),
        })
        .collect()
}

/// What node `n` must hold for chunk `k`: the source holds k + 1; every other node the
/// sum of its parents plus its own index, plus its feedback sources' values of chunk
/// k − 1 (none before chunk 0).
pub fn expected(links: &[Links], n: usize, k: u64) -> u64 {
    if n == 0 {
        return k + 1;
    }
    let fed: u64 = match k {
        0 => 0,
        _ => links[n]
            .feedback_from
            .iter()
            .map(|&s| expected(links, s, k - 1))
            .sum(),
    };
    links[n]
        .parents
        .iter()
        .map(|&p| expected(links, p, k))
        .sum::<u64>()
        + fed
        + n as u64
}
