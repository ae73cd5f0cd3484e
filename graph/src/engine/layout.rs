//! The table's entries built from a graph: its nodes' processors taken out with their
//! output slots, the parts of the nodes that split their channels, and which entries are
//! read and by whom.

use afe_core::{Block, Part};

use super::NodeRt;
use crate::graph::{Graph, Node};
use crate::protocol::Links;

/// The parts of each node whose processor splits its channels into `parts_per_node`
/// (none with one worker), by node index.
pub(super) fn split_nodes(graph: &mut Graph, parts_per_node: usize) -> Vec<(usize, Vec<Part>)> {
    if parts_per_node < 2 {
        return Vec::new();
    }
    let mut split = Vec::new();
    for (i, node) in graph.nodes.iter_mut().enumerate() {
        if let Some(parts) = node
            .processor
            .as_mut()
            .and_then(|p| p.channel_split())
            .and_then(|s| s.split(parts_per_node))
        {
            split.push((i, parts));
        }
    }
    split
}

/// The table's entries of the graph's nodes, their processors taken from `graph`: each
/// with its output slots, its parts' entries and whether it absorbs a whole signal.
pub(super) fn node_runtimes(
    graph: &mut Graph,
    part_entries: &[Vec<usize>],
    labels: &[String],
    absorbs: &[bool],
) -> Vec<NodeRt> {
    graph
        .nodes
        .iter_mut()
        .zip(part_entries)
        .enumerate()
        .map(|(i, (node, parts))| {
            // slot 1 stands for chunk −1: a feedback source's last output before the
            // table was built, which its targets take with their chunk 0
            let last = node
                .outputs
                .iter()
                .map(|b| {
                    let mut slot = b.empty_like();
                    slot.extend_from(b);
                    slot
                })
                .collect();
            let mut r = NodeRt::new(
                labels[i].clone(),
                node.processor.take(),
                [node.outputs.iter().map(Block::empty_like).collect(), last],
                &node.parents,
            );
            r.feedback = node.feedback_from;
            r.parts = parts.clone().into();
            r.absorbs = absorbs.get(i).copied().unwrap_or(false);
            r
        })
        .collect()
}

/// The table's entries (at `entries`) of `node`'s parts, reading its parents, with room
/// for as many rows as the node's own blocks (see `Manager::prepare`).
pub(super) fn part_runtimes(
    node: &Node,
    parts: Vec<Part>,
    entries: &[usize],
    labels: &[String],
) -> Vec<NodeRt> {
    let rows = node.outputs.iter().map(Block::room).max().unwrap_or(0);
    parts
        .into_iter()
        .zip(entries)
        .map(|(part, &entry)| {
            let blocks = || {
                part.widths
                    .iter()
                    .map(|&w| Block::with_room(w, rows))
                    .collect()
            };
            NodeRt::new(
                labels[entry].clone(),
                Some(part.processor),
                [blocks(), blocks()],
                &node.parents,
            )
        })
        .collect()
}

/// Marks each entry read (by a child with a processor, or through feedback) and whether
/// a child on another worker reads it (its output lines are then claimed). A child
/// without a processor, one that waits aside, reads nothing.
pub(super) fn mark_readers(rt: &mut [NodeRt], links: &[Links], home: &[usize]) {
    let reads: Vec<bool> = rt
        .iter_mut()
        .map(|r| r.processor.get_mut().is_some())
        .collect();
    for (e, r) in rt.iter_mut().enumerate() {
        let readers = || links[e].children.iter().filter(|&&c| reads[c]);
        r.read = readers().next().is_some() || !links[e].feedback_to.is_empty();
        r.claims = readers().any(|&c| home[c] != home[e]);
    }
}
