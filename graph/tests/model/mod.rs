//! What the loom models share: the graph's links, as `Engine::install` makes them, and the
//! value each node must hold for a chunk.

use crate::protocol::Links;

/// The links of the graph of `parents` (node 0 is the source); with `caller_reads`, every
/// node but the source has the caller as an extra reader, as in the engine.
pub fn links(parents: &[&[usize]], caller_reads: bool) -> Vec<Links> {
    let n = parents.len();
    let mut children = vec![Vec::new(); n];
    for (i, ps) in parents.iter().enumerate() {
        for &p in ps.iter() {
            children[p].push(i);
        }
    }
    (0..n)
        .map(|i| Links {
            parents: parents[i].to_vec().into(),
            children: children[i].clone().into(),
            readers: children[i].len() as u32 + u32::from(caller_reads && i != 0),
        })
        .collect()
}

/// What node `n` must hold for chunk `k`: the source holds k + 1; every other node the
/// sum of its parents plus its own index.
pub fn expected(links: &[Links], n: usize, k: u64) -> u64 {
    if n == 0 {
        return k + 1;
    }
    links[n]
        .parents
        .iter()
        .map(|&p| expected(links, p, k))
        .sum::<u64>()
        + n as u64
}
