//! The processor DAG and its sequential executor (the reference for every scheduler).

use std::sync::Arc;

use afe_core::denormals::FlushDenormals;
use afe_core::{Block, BuildContext, Configured, ParamMap, Processor, SignalInfo};
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
    /// The node's parameters, parsed once from the request's map into the processor's
    /// typed parameters (`None` for the source node); the nodes that one request places
    /// side by side (left and right ear) share it.
    pub config: Option<Arc<dyn Configured>>,
    /// The request's parameter map the node was configured from, kept only to configure
    /// it again with one parameter changed (see `Graph::modify`).
    pub request_params: ParamMap,
    /// 1-based instance number among the nodes of the same name and channel.
    pub instance: usize,
    /// Canonical own parameters (used to share nodes between requests).
    pub params: ParamMap,
    /// Parent outputs, left then right for binaural nodes.
    pub parents: Vec<OutputRef>,
    /// The feedback output of a node above this one (a later node) that this node takes
    /// before each chunk from the previous chunk (the MOC feeding the filterbank).
    pub feedback_from: Option<OutputRef>,
    /// The computation; `None` for the input node (and while the concurrent executor
    /// holds it).
    pub processor: Option<Box<dyn Processor>>,
    /// Whether the processor takes a whole signal block by block (see
    /// [`afe_core::WholeSignal`]), known while the executor holds it.
    pub absorbs: bool,
    /// New output of the last chunk, one block per output.
    pub outputs: Vec<Block>,
    /// Description of each output.
    pub infos: Vec<SignalInfo>,
    /// Ear of each output.
    pub channels: Vec<Channel>,
    /// The largest factor by which the processor raises its input's amplitude (see
    /// `Built::input_gain`).
    pub input_gain: f64,
}

/// The nodes in creation order, which is a topological order (parents come first).
/// Node 0 holds the input signals.
pub(crate) struct Graph {
    pub nodes: Vec<Node>,
    /// What nodes are built in (the head's pose, when a node starts).
    pub context: BuildContext,
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
            config: None,
            request_params: ParamMap::new(),
            instance: 1,
            params: ParamMap::new(),
            parents: Vec::new(),
            feedback_from: None,
            processor: None,
            absorbs: false,
            outputs: vec![Block::new(1); ears],
            infos: vec![SignalInfo::time_domain(fs); ears],
            channels,
            input_gain: 1.0,
        };
        Graph {
            nodes: vec![input],
            context: BuildContext::default(),
        }
    }

    /// The node that raises the input's amplitude most, and by how much (the input
    /// node, by 1, where none does).
    pub fn largest_input_gain(&self) -> (&'static str, f64) {
        (self.nodes.iter())
            .map(|n| (n.name, n.input_gain))
            .fold(("input", 1.0), |a, b| if b.1 > a.1 { b } else { a })
    }

    /// Copies the new input of a chunk into the input node (one slice per ear).
    pub fn load_input(&mut self, chunk: &[&[f64]]) {
        for (block, ear) in self.nodes[0].outputs.iter_mut().zip(chunk) {
            block.resize_to(ear.len()).copy_from_slice(ear);
        }
    }

    /// Runs every node once, in order, on its parents' new output; a node that takes
    /// feedback first receives its source's output of the previous chunk (still in the
    /// source's blocks, since the source comes later).
    pub fn run_sequential(&mut self) {
        let _flush = FlushDenormals::enable();
        for i in 1..self.nodes.len() {
            if let Some(f) = self.nodes[i].feedback_from {
                let (below, above) = self.nodes.split_at_mut(f.node);
                let block = &above[0].outputs[f.output];
                let to = below[i].processor.as_mut().and_then(|p| p.feedback());
                if let (false, Some(to)) = (block.is_empty(), to) {
                    to.receive_feedback(block);
                }
            }
            self.run_node(i);
        }
    }

    /// Runs node `i` on its parents' new output.
    pub(crate) fn run_node(&mut self, i: usize) {
        self.feed_node(i, |p, inputs, outputs| p.process(inputs, outputs));
    }

    /// Calls `f` with node `i`'s processor, its parents' new output and its outputs.
    pub(crate) fn feed_node(
        &mut self,
        i: usize,
        f: impl FnOnce(&mut dyn Processor, &[&Block], &mut [Block]),
    ) {
        let _flush = FlushDenormals::enable();
        let (before, rest) = self.nodes.split_at_mut(i);
        let node = &mut rest[0];
        let first = node.parents[0];
        let first_block = &before[first.node].outputs[first.output];
        let mut inputs: [&Block; MAX_INPUTS] = [first_block; MAX_INPUTS];
        for (slot, p) in inputs.iter_mut().zip(&node.parents).skip(1) {
            *slot = &before[p.node].outputs[p.output];
        }
        if let Some(proc_) = node.processor.as_mut() {
            f(
                proc_.as_mut(),
                &inputs[..node.parents.len()],
                &mut node.outputs,
            );
        }
    }

    /// Which nodes a whole signal reaches block by block although they are not
    /// chunk-invariant (`invariant` from [`Graph::invariant_nodes`]): those whose
    /// processor absorbs a whole signal and whose parents are all invariant, so that
    /// their input need not be joined.
    pub fn absorbing_nodes(&self, invariant: &[bool]) -> Vec<bool> {
        self.nodes
            .iter()
            .zip(invariant)
            .map(|(node, inv)| {
                !inv && node.absorbs && node.parents.iter().all(|p| invariant[p.node])
            })
            .collect()
    }

    /// Which nodes have a chunk-invariant processor and only such nodes below them. A
    /// node taking feedback is not: the feedback lags one chunk behind (and a whole
    /// signal, as one call in the AFE, is processed without it).
    pub fn invariant_nodes(&self) -> Vec<bool> {
        let mut invariant = vec![true; self.nodes.len()];
        for (i, node) in self.nodes.iter().enumerate().skip(1) {
            invariant[i] = node.config.as_ref().is_none_or(|c| c.chunk_invariant())
                && node.feedback_from.is_none()
                && node.parents.iter().all(|p| invariant[p.node]);
        }
        invariant
    }

    /// How a whole signal may be fed in chunks and still give one call's output:
    /// `Some(n)` when every chunk size works once the first chunk holds at least `n`
    /// input samples (or the whole signal; `n` = 0 for a chunk-invariant graph), `None`
    /// when some node needs its whole input in one call.
    pub fn one_call_prefix(&self) -> Option<usize> {
        let fs = self.nodes[0].infos.first().map_or(0.0, |i| i.fs_hz);
        let mut prefix = 0;
        for node in self.nodes.iter().skip(1) {
            let own = match &node.config {
                Some(c) if !c.chunk_invariant() => c
                    .one_call_prefix_s()
                    .map(|s| ((s.max(0.0) * fs).ceil() as usize).saturating_add(1)),
                _ => Some(0),
            };
            match own {
                Some(n) if node.feedback_from.is_none() => prefix = prefix.max(n),
                _ => return None,
            }
        }
        Some(prefix)
    }

    /// Lends the joining buffers of the `nodes` (the blocks in `whole`, sized for a whole
    /// signal) to their outputs, so that each chunk is written in place instead of being
    /// copied there: each buffer takes its output's place, and `whole` keeps the output's
    /// own block until [`Graph::return_buffers`]. [`Graph::seal_lent`] before each chunk
    /// keeps what they hold.
    pub fn lend_buffers(
        &mut self,
        whole: &mut [Vec<Option<Block>>],
        nodes: &[bool],
    ) -> Vec<OutputRef> {
        let mut lent = Vec::new();
        for (i, (node, outputs)) in self.nodes.iter_mut().zip(whole).enumerate() {
            if !nodes[i] {
                continue;
            }
            for (output, (out, acc)) in node.outputs.iter_mut().zip(outputs).enumerate() {
                if let Some(acc) = acc {
                    std::mem::swap(out, acc);
                    lent.push(OutputRef { node: i, output });
                }
            }
        }
        lent
    }

    /// Seals what the `lent` buffers hold, so that the next chunk is written after it
    /// (see [`Block::seal`]).
    pub fn seal_lent(&mut self, lent: &[OutputRef]) {
        for r in lent {
            self.nodes[r.node].outputs[r.output].seal();
        }
    }

    /// Takes the `lent` buffers back into `whole`, showing all they hold, and gives the
    /// outputs their own blocks again.
    pub fn return_buffers(&mut self, whole: &mut [Vec<Option<Block>>], lent: &[OutputRef]) {
        for r in lent {
            if let Some(acc) = whole[r.node][r.output].as_mut() {
                let out = &mut self.nodes[r.node].outputs[r.output];
                std::mem::swap(out, acc);
                acc.unseal();
                out.clear();
            }
        }
    }

    /// Resets every processor and clears every output.
    pub fn reset(&mut self) {
        let _flush = FlushDenormals::enable();
        for node in &mut self.nodes {
            if let Some(p) = node.processor.as_mut() {
                p.reset();
            }
            node.outputs.iter_mut().for_each(Block::clear);
        }
    }
}
