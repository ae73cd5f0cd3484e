//! The concurrent executor's graph compiler: from the graph's shape (each node's parents,
//! feedback source and the parts its processor splits into) to the table's layout (its
//! entries, their links, readers and home threads). Pure data, which the engine then fills
//! with processors and blocks ([`crate::engine::Engine::install`]); kept apart from the
//! execution so that it is tested on its own, printed.

use crate::graph::OutputRef;
use crate::placement;
use crate::protocol::Links;

/// What the compiler needs to know of one node of the graph.
#[derive(Debug, Clone)]
pub(crate) struct NodeShape {
    /// Its label, for the printed table.
    pub label: String,
    /// The outputs it reads, in order.
    pub parents: Vec<OutputRef>,
    /// The feedback output it takes from the previous chunk.
    pub feedback_from: Option<OutputRef>,
    /// Parts its processor runs as (0: not split); the node then joins them.
    pub parts: usize,
}

/// The table's layout: the graph's nodes as its first entries, in order, then the parts of
/// the split nodes, each split node's parts together.
#[derive(Debug)]
pub(crate) struct Compiled {
    /// Per node of the graph: the entries of its parts (empty where it is not split).
    pub part_entries: Vec<Vec<usize>>,
    /// Per entry: its links (parents, children, readers, feedback).
    pub links: Vec<Links>,
    /// Per entry: the computing thread it is taken by first.
    pub home: Vec<usize>,
    /// Per entry: the label it is shown with (a part's is its node's, `/part<j>`).
    pub labels: Vec<String>,
}

/// Lays out the table of `nodes` (node 0: the input) for `threads` computing threads: a
/// part reads its node's inputs, a split node reads its parts besides, the caller collects
/// every node but the input and the parts, and homes spread the work (see
/// [`crate::placement`]).
pub(crate) fn compile(nodes: &[NodeShape], threads: usize) -> Compiled {
    let n = nodes.len();
    let mut part_entries: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut inputs: Vec<&[OutputRef]> = nodes.iter().map(|s| s.parents.as_slice()).collect();
    let mut labels: Vec<String> = nodes.iter().map(|s| s.label.clone()).collect();
    for (i, node) in nodes.iter().enumerate() {
        for j in 0..node.parts {
            part_entries[i].push(inputs.len());
            inputs.push(&node.parents);
            labels.push(format!("{}/part{j}", node.label));
        }
    }
    let total = inputs.len();
    // each entry's distinct parent entries: its inputs' nodes and, for a split node, its
    // parts
    let parents: Vec<Vec<usize>> = inputs
        .iter()
        .enumerate()
        .map(|(i, own)| {
            let own_parts = part_entries.get(i).into_iter().flatten().copied();
            let mut p: Vec<usize> = own.iter().map(|r| r.node).chain(own_parts).collect();
            p.sort_unstable();
            p.dedup();
            p
        })
        .collect();
    let split_parts: Vec<&[usize]> = part_entries
        .iter()
        .filter(|p| !p.is_empty())
        .map(Vec::as_slice)
        .collect();
    let home = placement::homes(&parents, &split_parts, threads);
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); total];
    for (i, ps) in parents.iter().enumerate() {
        for &p in ps {
            children[p].push(i);
        }
    }
    let mut feedback_to: Vec<Vec<usize>> = vec![Vec::new(); total];
    for (i, node) in nodes.iter().enumerate() {
        if let Some(f) = node.feedback_from {
            feedback_to[f.node].push(i);
        }
    }
    let links = parents
        .into_iter()
        .enumerate()
        .map(|(i, parents)| {
            // the caller collects the graph's nodes, not the input or the parts
            let sink = u32::from(i != 0 && i < n);
            let feedback_from = nodes.get(i).and_then(|s| s.feedback_from);
            Links {
                parents: parents.into(),
                children: children[i].clone().into(),
                readers: (children[i].len() + feedback_to[i].len()) as u32 + sink,
                feedback_from: feedback_from.map(|f| f.node).into_iter().collect(),
                feedback_to: feedback_to[i].clone().into(),
            }
        })
        .collect();
    Compiled {
        part_entries,
        links,
        home,
        labels,
    }
}

impl std::fmt::Display for Compiled {
    /// One line per entry: `entry label <- parents -> children, readers, feedback, home`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (e, l) in self.links.iter().enumerate() {
            write!(
                f,
                "{e} {} <- {:?} -> {:?} readers {}",
                self.labels[e], l.parents, l.children, l.readers
            )?;
            if !l.feedback_from.is_empty() {
                write!(f, " feedback from {:?}", l.feedback_from)?;
            }
            if !l.feedback_to.is_empty() {
                write!(f, " feedback to {:?}", l.feedback_to)?;
            }
            writeln!(f, " home {}", self.home[e])?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(label: &str, parents: &[(usize, usize)], parts: usize) -> NodeShape {
        NodeShape {
            label: label.into(),
            parents: parents
                .iter()
                .map(|&(node, output)| OutputRef { node, output })
                .collect(),
            feedback_from: None,
            parts,
        }
    }

    /// A binaural cue chain (the input, two filterbanks, a cross-correlation of both)
    /// with the correlation split in two on two threads: the parts read what their node
    /// reads, the node reads them besides, only the graph's nodes but the input are
    /// collected (one reader more), and the parts go to both threads.
    #[test]
    fn a_split_node_reads_its_parts_and_its_parts_its_inputs() {
        let nodes = [
            node("time#0", &[], 0),
            node("filterbank#0", &[(0, 0)], 0),
            node("filterbank#1", &[(0, 1)], 0),
            node("crosscorrelation#0", &[(1, 0), (2, 0)], 2),
        ];
        let table = compile(&nodes, 2).to_string();
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines.len(), 6, "{table}");
        assert!(
            lines[0].starts_with("0 time#0 <- [] -> [1, 2] readers 2 "),
            "{table}"
        );
        assert!(
            lines[1].starts_with("1 filterbank#0 <- [0] -> [3, 4, 5] readers 4 "),
            "{table}"
        );
        assert!(
            lines[2].starts_with("2 filterbank#1 <- [0] -> [3, 4, 5] readers 4 "),
            "{table}"
        );
        assert!(
            lines[3].starts_with("3 crosscorrelation#0 <- [1, 2, 4, 5] -> [] readers 1 "),
            "{table}"
        );
        assert!(
            lines[4].starts_with("4 crosscorrelation#0/part0 <- [1, 2] -> [3] readers 1 "),
            "{table}"
        );
        assert!(
            lines[5].starts_with("5 crosscorrelation#0/part1 <- [1, 2] -> [3] readers 1 "),
            "{table}"
        );
        let compiled = compile(&nodes, 2);
        assert_eq!(compiled.part_entries[3], [4, 5]);
        assert_ne!(compiled.home[4], compiled.home[5], "{table}");
    }

    /// A feedback edge (the MOC's gains to the DRNL below it) is no parent link: the
    /// source counts its target among its readers, the target waits for the source's
    /// previous chunk.
    #[test]
    fn a_feedback_edge_adds_a_reader_and_no_parent() {
        let mut nodes = vec![
            node("time#0", &[], 0),
            node("filterbank#0", &[(0, 0)], 0),
            node("moc#0", &[(1, 0)], 0),
        ];
        nodes[1].feedback_from = Some(OutputRef { node: 2, output: 0 });
        let table = compile(&nodes, 1).to_string();
        let lines: Vec<&str> = table.lines().collect();
        assert!(
            lines[1].starts_with("1 filterbank#0 <- [0] -> [2] readers 2 feedback from [2] "),
            "{table}"
        );
        assert!(
            lines[2].starts_with("2 moc#0 <- [1] -> [] readers 2 feedback to [1] "),
            "{table}"
        );
    }
}
