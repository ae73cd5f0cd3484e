//! The processor DAG and its sequential executor (the reference for every scheduler).

use afe_core::{Block, ParamMap, Processor, SignalInfo};
use afe_processors::RequestDef;

/// Which ear a node output belongs to, named as in the AFE's output signals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Channel {
    /// Left ear.
    Left,
    /// Right ear.
    Right,
    /// A single-channel input, or a binaural cue computed from both ears.
    Mono,
}

impl Channel {
    /// The AFE name: `left`, `right` or `mono`.
    pub fn as_str(self) -> &'static str {
        match self {
            Channel::Left => "left",
            Channel::Right => "right",
            Channel::Mono => "mono",
        }
    }
}

/// Most inputs a node may read: left and right of a binaural node, each with one extra
/// input (e.g. a map reading the ratemap beside its onset strength).
pub const MAX_INPUTS: usize = 4;

/// A reference to one output of one node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct OutputRef {
    /// Index of the node in the graph.
    pub node: usize,
    /// Index of the output within that node.
    pub output: usize,
}

/// One processor instance of the graph.
pub(crate) struct Node {
    /// Request name of what the node computes (`input` for the source node).
    pub name: &'static str,
    /// What the node computes (`None` for the source node).
    pub def: Option<&'static RequestDef>,
    /// The request parameters the node was built from (to rebuild it after an edit).
    pub build_params: ParamMap,
    /// 1-based instance number among the nodes of the same name and channel.
    pub instance: usize,
    /// Canonical own parameters (used to share nodes between requests).
    pub params: ParamMap,
    /// Parent outputs, left then right for binaural nodes.
    pub parents: Vec<OutputRef>,
    /// The computation; `None` for the input node.
    pub processor: Option<Box<dyn Processor>>,
    /// New output of the last chunk, one block per output.
    pub outputs: Vec<Block>,
    /// Description of each output.
    pub infos: Vec<SignalInfo>,
    /// Ear of each output.
    pub channels: Vec<Channel>,
}

/// The nodes in creation order, which is a topological order (parents come first).
/// Node 0 holds the input signals.
pub(crate) struct Graph {
    pub nodes: Vec<Node>,
}

impl Graph {
    /// A graph with only the input node, for `ears` input signals at `fs` Hz.
    pub fn new(fs: f64, ears: usize) -> Self {
        let channels = if ears == 2 {
            vec![Channel::Left, Channel::Right]
        } else {
            vec![Channel::Mono]
        };
        let input = Node {
            name: "input",
            def: None,
            build_params: ParamMap::new(),
            instance: 1,
            params: ParamMap::new(),
            parents: Vec::new(),
            processor: None,
            outputs: vec![Block::new(1); ears],
            infos: vec![SignalInfo::time_domain(fs); ears],
            channels,
        };
        Graph { nodes: vec![input] }
    }

    /// Copies the new input of a chunk into the input node (one slice per ear).
    pub fn load_input(&mut self, chunk: &[&[f64]]) {
        for (block, ear) in self.nodes[0].outputs.iter_mut().zip(chunk) {
            block.resize_to(ear.len()).copy_from_slice(ear);
        }
    }

    /// Runs every node once, in order, on its parents' new output.
    pub fn run_sequential(&mut self) {
        for i in 1..self.nodes.len() {
            let (before, rest) = self.nodes.split_at_mut(i);
            let node = &mut rest[0];
            let first = node.parents[0];
            let first_block = &before[first.node].outputs[first.output];
            let mut inputs: [&Block; MAX_INPUTS] = [first_block; MAX_INPUTS];
            for (slot, p) in inputs.iter_mut().zip(&node.parents).skip(1) {
                *slot = &before[p.node].outputs[p.output];
            }
            if let Some(proc_) = node.processor.as_mut() {
                proc_.process(&inputs[..node.parents.len()], &mut node.outputs);
            }
        }
    }

    /// Resets every processor and clears every output.
    pub fn reset(&mut self) {
        for node in &mut self.nodes {
            if let Some(p) = node.processor.as_mut() {
                p.reset();
            }
            node.outputs.iter_mut().for_each(Block::clear);
        }
    }
}
