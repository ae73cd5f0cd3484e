//! A whole signal through the graph, as one call of the AFE's `processSignal` gives it:
//! the nodes whose whole chain is chunk-invariant run in blocks (on this thread, or on
//! the concurrent executor's threads with vertical and horizontal concurrency), then the
//! nodes that must see the signal in one call run once each on their parents' joined
//! outputs (in order, or on several threads as their parents finish). Every node makes
//! the same calls on the same data either way, so the numbers are the same bit for bit.

use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::{Condvar, Mutex, RwLock};

use afe_core::denormals::FlushDenormals;
use afe_core::{Block, CancelToken, Error, Processor, Result};

use crate::engine::Engine;
use crate::graph::{Graph, OutputRef};
use crate::work;
use crate::WHOLE_SIGNAL_BLOCK;

/// Which nodes of a whole-signal run take it how, and which outputs go on block by block.
struct Plan<'a> {
    /// Nodes run in blocks: chunk-invariant with only such nodes below them.
    invariant: Vec<bool>,
    /// Nodes that take the blocks as they come and finish once (see
    /// [`Graph::absorbing_nodes`]).
    absorbing: Vec<bool>,
    /// Per node and output: handed to the caller block by block rather than joined.
    streamed: &'a [Vec<bool>],
    /// The run's stop request, checked before each block and node.
    cancel: &'a CancelToken,
}

impl Graph {
    /// Processes a whole signal (one slice per ear) as one call would, putting every
    /// node's output into `whole` (per node and output; empty blocks, those of invariant
    /// nodes sized for the signal) where it has a block, which it must for every input
    /// of a node that is neither chunk-invariant nor absorbing: the invariant nodes run in
    /// blocks of [`WHOLE_SIGNAL_BLOCK`] samples (bit-identical to one call, with the
    /// intermediate signals in cache), then every other node runs once on its parents'
    /// joined outputs. Each block of the invariant outputs marked in `streamed` goes to
    /// `each_block`. With an `engine`, both parts use its threads; without, this one.
    /// `cancel` stops it at the next block or node with [`Error::Interrupted`].
    pub fn run_whole(
        &mut self,
        signal: &[&[f64]],
        whole: &mut [Vec<Option<Block>>],
        streamed: &[Vec<bool>],
        each_block: &mut dyn FnMut(OutputRef, &Block),
        engine: Option<&mut Engine>,
        cancel: &CancelToken,
    ) -> Result<()> {
        let block = WHOLE_SIGNAL_BLOCK;
        let invariant = self.invariant_nodes();
        let absorbing = self.absorbing_nodes(&invariant);
        let plan = Plan {
            invariant,
            absorbing,
            streamed,
            cancel,
        };
        let threads = engine.as_ref().map_or(1, |e| e.threads());
        let len = signal.first().map_or(0, |c| c.len());
        let blocks = (0..len).step_by(block.max(1)).map(|start| {
            let end = (start + block).min(len);
            signal.iter().map(|c| &c[start..end]).collect::<Vec<_>>()
        });
        match engine {
            Some(engine) => self.blocks_on(engine, blocks, whole, &plan, each_block)?,
            None => self.blocks_here(blocks, whole, &plan, each_block)?,
        }
        self.run_per_chunk_nodes(whole, &plan, threads, len)
    }

    /// The invariant and absorbing nodes over the signal's `blocks` (one slice per ear
    /// each), on this thread; the joined outputs are written in place (see
    /// [`Graph::lend_buffers`]).
    fn blocks_here<'s>(
        &mut self,
        blocks: impl Iterator<Item = Vec<&'s [f64]>>,
        whole: &mut [Vec<Option<Block>>],
        plan: &Plan<'_>,
        each_block: &mut dyn FnMut(OutputRef, &Block),
    ) -> Result<()> {
        let lent = self.lend_buffers(whole, &plan.invariant);
        for part in blocks {
            if plan.cancel.is_cancelled() {
                self.return_buffers(whole, &lent);
                return Err(Error::Interrupted);
            }
            self.seal_lent(&lent);
            self.load_input(&part);
            for i in 0..self.nodes.len() {
                if plan.absorbing[i] {
                    self.feed_node(i, |p, inputs, _| {
                        if let Some(whole) = p.whole_signal() {
                            whole.absorb(inputs);
                        }
                    });
                } else if plan.invariant[i] {
                    if i > 0 {
                        self.run_node(i);
                    }
                    for (output, out) in self.nodes[i].outputs.iter().enumerate() {
                        if plan.streamed[i][output] {
                            each_block(OutputRef { node: i, output }, out);
                        }
                    }
                }
            }
        }
        self.return_buffers(whole, &lent);
        Ok(())
    }

    /// The invariant and absorbing nodes over the signal's `blocks`, on the `engine`'s
    /// threads: the other nodes' processors wait aside, and the nodes keep their joined
    /// outputs in `whole`'s buffers themselves (see [`Engine::lend_kept`]).
    fn blocks_on<'s>(
        &mut self,
        engine: &mut Engine,
        blocks: impl Iterator<Item = Vec<&'s [f64]>>,
        whole: &mut [Vec<Option<Block>>],
        plan: &Plan<'_>,
        each_block: &mut dyn FnMut(OutputRef, &Block),
    ) -> Result<()> {
        let aside: Vec<Option<Box<dyn Processor>>> = (0..self.nodes.len())
            .map(|i| {
                let waits = !plan.invariant[i] && !plan.absorbing[i];
                self.nodes[i].processor.take_if(|_| waits)
            })
            .collect();
        engine.install_absorbing(self, &plan.absorbing);
        // the caller copies only the outputs it hands on; the joined ones their nodes
        // append themselves
        engine.set_copied(plan.streamed.to_vec());
        let streamed: Vec<OutputRef> = plan
            .streamed
            .iter()
            .enumerate()
            .flat_map(|(node, s)| {
                let outputs = s.iter().enumerate().filter(|(_, s)| **s);
                outputs.map(move |(output, _)| OutputRef { node, output })
            })
            .collect();
        engine.lend_kept(whole, &plan.invariant);
        let mut collect = |engine: &mut Engine| -> Result<()> {
            engine.collect()?;
            for &r in &streamed {
                if let Some(b) = engine.block(r) {
                    each_block(r, b);
                }
            }
            Ok(())
        };
        // (a panic in `each_block` or an input copy still gives the buffers back)
        let fed = catch_unwind(AssertUnwindSafe(|| {
            let mut fed = Ok(());
            for part in blocks {
                // the input itself, where a node taking the signal in one call reads it
                // (the engine's source is not collected)
                for (acc, ear) in whole[0].iter_mut().zip(&part) {
                    if let Some(acc) = acc {
                        acc.extend_from_slice(ear);
                    }
                }
                fed = fed
                    .and_then(|()| match plan.cancel.is_cancelled() {
                        true => Err(Error::Interrupted),
                        false => engine.submit(&part),
                    })
                    .and_then(|()| match engine.in_flight() {
                        2.. => collect(engine),
                        _ => Ok(()),
                    });
                if fed.is_err() {
                    break;
                }
            }
            while fed.is_ok() && engine.in_flight() > 0 {
                fed = collect(engine);
            }
            fed
        }));
        let idle = engine.return_kept(whole);
        engine.uninstall(self);
        for (node, p) in self.nodes.iter_mut().zip(aside) {
            if p.is_some() {
                node.processor = p;
            }
        }
        fed.unwrap_or_else(|panic| resume_unwind(panic)).and(idle)
    }

    /// Runs every node that is not invariant once, on its parents' joined outputs in
    /// `whole` (an absorbing one finishes), and moves its outputs into their buffers in
    /// `whole`: in order on this thread, or on `threads` threads, each node as soon as
    /// its parents are done. A processor's panic is raised again on this thread; the
    /// plan's stop request stops it before the next node.
    fn run_per_chunk_nodes(
        &mut self,
        whole: &mut [Vec<Option<Block>>],
        plan: &Plan<'_>,
        threads: usize,
        len: usize,
    ) -> Result<()> {
        let order: Vec<usize> = (0..self.nodes.len())
            .filter(|&i| !plan.invariant[i])
            .collect();
        let mut waiting = vec![0usize; self.nodes.len()];
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); self.nodes.len()];
        for &i in &order {
            let mut parents: Vec<usize> = self.nodes[i].parents.iter().map(|p| p.node).collect();
            parents.sort_unstable();
            parents.dedup();
            for p in parents.into_iter().filter(|&p| !plan.invariant[p]) {
                children[p].push(i);
                waiting[i] += 1;
            }
        }
        // per node: its processor and outputs, for the thread that runs it
        let fs = self.nodes[0].infos.first().map_or(1.0, |i| i.fs_hz);
        let mut jobs: Vec<Option<Mutex<Job<'_>>>> = self
            .nodes
            .iter_mut()
            .enumerate()
            .map(|(i, node)| {
                (!plan.invariant[i]).then(|| {
                    Mutex::new(Job {
                        name: node.name,
                        processor: &mut node.processor,
                        outputs: &mut node.outputs,
                        rates: node.infos.iter().map(|info| info.fs_hz / fs).collect(),
                        parents: &node.parents,
                        absorbing: plan.absorbing[i],
                        samples: len,
                    })
                })
            })
            .collect();
        let joined: Vec<RwLock<&mut Vec<Option<Block>>>> =
            whole.iter_mut().map(RwLock::new).collect();
        if threads <= 1 || order.len() <= 1 {
            for &i in &order {
                if plan.cancel.is_cancelled() {
                    return Err(Error::Interrupted);
                }
                if let Some(job) = jobs[i].as_mut() {
                    run_job(job.get_mut().unwrap_or_else(|e| e.into_inner()), i, &joined)?;
                }
            }
            return Ok(());
        }
        let ready: Vec<usize> = order.iter().copied().filter(|&i| waiting[i] == 0).collect();
        let board = Board {
            state: Mutex::new(Progress {
                ready,
                waiting,
                left: order.len(),
                panic: None,
                failed: None,
            }),
            changed: Condvar::new(),
            cancel: plan.cancel,
        };
        let jobs = &jobs;
        let (joined, children) = (&joined, &children);
        std::thread::scope(|scope| {
            for _ in 1..threads.min(order.len()) {
                scope.spawn(|| board.work(jobs, joined, children));
            }
            board.work(jobs, joined, children);
        });
        let state = board.state.into_inner().unwrap_or_else(|e| e.into_inner());
        if let Some(panic) = state.panic {
            resume_unwind(panic);
        }
        if let Some(e) = state.failed {
            return Err(e);
        }
        match state.left {
            0 => Ok(()),
            _ => Err(Error::Interrupted),
        }
    }
}

/// One node that takes the whole signal in one call: what the thread running it needs.
struct Job<'a> {
    name: &'static str,
    processor: &'a mut Option<Box<dyn Processor>>,
    outputs: &'a mut Vec<Block>,
    /// Per output, frames per input sample.
    rates: Vec<f64>,
    parents: &'a [OutputRef],
    absorbing: bool,
    /// Input samples of the whole signal.
    samples: usize,
}

/// Runs node `i`'s job on its parents' joined outputs and moves its outputs into its
/// buffers among the `joined` (those it has: the ones read later). Its outputs are
/// reserved for the whole signal first, so that memory that runs short is an
/// [`Error::AllocationFailed`] rather than an abort in the processor.
fn run_job(job: &mut Job<'_>, i: usize, joined: &[RwLock<&mut Vec<Option<Block>>>]) -> Result<()> {
    for (out, rate) in job.outputs.iter_mut().zip(&job.rates) {
        out.clear();
        reserve(out, job.samples, *rate, job.name)?;
    }
    {
        let _flush = FlushDenormals::enable();
        // parents are done: their buffers are only read from now on
        let guards: Vec<_> = job
            .parents
            .iter()
            .map(|p| joined[p.node].read().unwrap_or_else(|e| e.into_inner()))
            .collect();
        let inputs: Option<Vec<&Block>> = job
            .parents
            .iter()
            .zip(&guards)
            .map(|(p, g)| g[p.output].as_ref())
            .collect();
        match (job.processor.as_deref_mut(), inputs) {
            (Some(p), _) if job.absorbing => {
                if let Some(whole) = p.whole_signal() {
                    whole.finish(job.outputs);
                }
            }
            (Some(p), Some(inputs)) => p.process(&inputs, job.outputs),
            _ => {}
        }
    }
    let mut own = joined[i].write().unwrap_or_else(|e| e.into_inner());
    // the whole output moves into its empty buffer rather than being copied
    for (acc, out) in own.iter_mut().zip(job.outputs.iter_mut()) {
        if let Some(acc) = acc {
            std::mem::swap(acc, out);
        }
    }
    Ok(())
}

/// Makes room in `block` for the frames of `samples` input samples at `rate` frames per
/// input sample, and one for rounding, or says which output of `node` did not fit.
pub(crate) fn reserve(
    block: &mut Block,
    samples: usize,
    rate: f64,
    node: &'static str,
) -> Result<()> {
    let frames = (samples as f64 * rate).ceil() as usize + 1;
    block
        .try_reserve_frames(frames)
        .map_err(|_| Error::AllocationFailed {
            need: work::size(frames as f64 * block.width() as f64 * 8.0),
            what: format!("the whole-signal output of {node}"),
        })
}

/// The nodes still to run, shared by the threads that run them.
struct Progress {
    /// Nodes whose parents are all done.
    ready: Vec<usize>,
    /// Per node, parents not yet done.
    waiting: Vec<usize>,
    /// Nodes not yet done.
    left: usize,
    /// The first processor panic: the others stop taking nodes.
    panic: Option<Box<dyn std::any::Any + Send>>,
    /// The first error (an output the memory could not take): the others stop too.
    failed: Option<Error>,
}

struct Board<'a> {
    state: Mutex<Progress>,
    changed: Condvar,
    cancel: &'a CancelToken,
}

impl Board<'_> {
    /// Takes ready nodes and runs them until every node is done (or one panicked).
    fn work(
        &self,
        jobs: &[Option<Mutex<Job<'_>>>],
        joined: &[RwLock<&mut Vec<Option<Block>>>],
        children: &[Vec<usize>],
    ) {
        loop {
            let i = {
                let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
                loop {
                    let stopped = s.panic.is_some() || s.failed.is_some();
                    if s.left == 0 || stopped || self.cancel.is_cancelled() {
                        return;
                    }
                    if let Some(i) = s.ready.pop() {
                        break i;
                    }
                    s = self.changed.wait(s).unwrap_or_else(|e| e.into_inner());
                }
            };
            let ran = catch_unwind(AssertUnwindSafe(|| match &jobs[i] {
                Some(job) => run_job(
                    &mut job.lock().unwrap_or_else(|e| e.into_inner()),
                    i,
                    joined,
                ),
                None => Ok(()),
            }));
            let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
            s.left -= 1;
            match ran {
                Ok(Err(e)) => s.failed = s.failed.take().or(Some(e)),
                Ok(Ok(())) => {
                    for &c in &children[i] {
                        s.waiting[c] -= 1;
                        if s.waiting[c] == 0 {
                            s.ready.push(c);
                        }
                    }
                }
                Err(panic) => s.panic = s.panic.take().or(Some(panic)),
            }
            self.changed.notify_all();
        }
    }
}
