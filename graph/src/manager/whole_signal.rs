//! A whole signal through the graph, as the AFE's `processSignal`: in blocks where that
//! gives one call's output (a chunk-invariant graph, or past the AGC's seeding time), the
//! outputs joined in buffers sized for the signal; otherwise the nodes that depend on
//! chunk boundaries get their whole input in one call, within a memory limit.

use afe_core::{Block, Error, Result};

use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};

use super::{BlockSink, Manager, WHOLE_SIGNAL_BLOCK, WHOLE_SIGNAL_LIMIT_MB};
use crate::block_input::{BlockInput, BlockSource};
use crate::graph::OutputRef;
use crate::whole_run::reserve;
use crate::work;

/// The address space a thread of a whole-signal call takes beyond the signals: its stack
/// (8 MiB by default) and the allocator's arena that its first allocation reserves
/// (64 MiB with glibc), bytes.
pub const THREAD_BYTES: f64 = 80e6;

impl Manager {
    /// Checks that a whole signal of `len` samples fits where [`Manager::process_signal`]
    /// must hold it in one call: the joined inputs and the outputs of the processors that
    /// take their whole input at once, requested outputs aside, within
    /// [`WHOLE_SIGNAL_LIMIT_MB`] (or `AFE_WHOLE_SIGNAL_LIMIT_MB`); and those with the
    /// requested outputs and the processors' working copies (see
    /// [`Manager::whole_signal_bytes`]) within the memory available
    /// ([`work::memory_available`]), else an [`Error::WholeSignalOverMemory`]. A graph
    /// that runs in blocks (see [`Manager::one_call_prefix`]) holds only its first block,
    /// which with a seeding time longer than a block (the AGC's) holds every node's
    /// output over that time; its outputs sized for the signal are reserved fallibly (an
    /// [`Error::AllocationFailed`] rather than an abort). A limit variable set to a value
    /// it does not accept is an [`Error::BadSetting`].
    pub fn check_whole_signal(&self, len: usize) -> Result<()> {
        let limit_mb = match work::setting(&work::WHOLE_SIGNAL_LIMIT_SETTING)? {
            Some(mb) => mb as u64,
            None => WHOLE_SIGNAL_LIMIT_MB,
        };
        let Some((bytes, what)) = self.one_call_share(len) else {
            return Ok(());
        };
        let need_mb = (bytes / 1e6).ceil() as u64;
        if need_mb > limit_mb {
            return Err(Error::WholeSignalTooLarge {
                seconds: len as f64 / self.fs,
                need_mb,
                limit_mb,
                what: what.join(", "),
            });
        }
        let need = self.whole_signal_bytes(len);
        match work::memory_available()? {
            Some(available) if need > available => Err(Error::WholeSignalOverMemory {
                seconds: len as f64 / self.fs,
                need: work::size(need),
                available: work::size(available),
                what: what.join(", "),
            }),
            _ => Ok(()),
        }
    }

    /// The bytes of intermediate signals a whole signal of `len` samples holds beyond the
    /// blocks of a chunk (requested outputs aside), and the nodes that make it hold them:
    /// `None` for a graph that runs in blocks of [`WHOLE_SIGNAL_BLOCK`].
    fn one_call_share(&self, len: usize) -> Option<(f64, Vec<&'static str>)> {
        match self.graph.one_call_prefix() {
            Some(prefix) if prefix <= WHOLE_SIGNAL_BLOCK => None,
            Some(prefix) => Some(self.first_block_bytes(prefix.min(len))),
            None => Some(self.one_call_bytes(len)),
        }
    }

    /// The memory a whole-signal call of `len` samples takes beyond its input (which the
    /// caller holds already), bytes: the intermediate signals of
    /// [`Manager::check_whole_signal`], the outputs it keeps (the requested ones, every
    /// one with [`Manager::set_keep_all`]), a working copy of each whole input a
    /// processor takes in one call (the ratemap smooths its whole input into a buffer
    /// of that size before framing it) and, per thread, its stack and allocator arena
    /// (80 MB). 0 for a graph that runs in blocks, whose outputs are reserved
    /// fallibly instead.
    pub fn whole_signal_bytes(&self, len: usize) -> f64 {
        let Some((intermediate, _)) = self.one_call_share(len) else {
            return 0.0;
        };
        let nodes = &self.graph.nodes;
        let kept: f64 = (nodes.iter().enumerate().skip(1))
            .flat_map(|(i, n)| {
                n.infos
                    .iter()
                    .enumerate()
                    .map(move |(o, info)| (i, o, info))
            })
            .filter(|&(node, output, _)| {
                self.keep_all || self.is_requested(OutputRef { node, output })
            })
            .map(|(_, _, info)| self.signal_bytes(info, len))
            .sum();
        let copies: f64 = match self.graph.one_call_prefix() {
            Some(_) => 0.0,
            None => {
                let invariant = self.graph.invariant_nodes();
                let absorbing = self.graph.absorbing_nodes(&invariant);
                (nodes.iter().enumerate())
                    .filter(|(i, _)| !invariant[*i] && !absorbing[*i])
                    .flat_map(|(_, n)| &n.parents)
                    .map(|p| self.signal_bytes(&nodes[p.node].infos[p.output], len))
                    .sum()
            }
        };
        let threads = self.threads().max(1) as f64;
        intermediate + kept + copies + threads * THREAD_BYTES
    }

    /// Bytes of the blocks every node writes over a first block of `len` samples (a
    /// seeding time longer than the usual block), and the nodes that ask for it.
    fn first_block_bytes(&self, len: usize) -> (f64, Vec<&'static str>) {
        let infos = self.graph.nodes.iter().flat_map(|n| &n.infos);
        let bytes = infos.map(|info| self.signal_bytes(info, len)).sum();
        (bytes, self.per_chunk_nodes())
    }

    /// The names of the nodes whose output depends on the chunking, each once.
    fn per_chunk_nodes(&self) -> Vec<&'static str> {
        let invariant = self.graph.invariant_nodes();
        let mut names = Vec::new();
        for (node, _) in self.graph.nodes.iter().zip(invariant).filter(|(_, i)| !i) {
            if !names.contains(&node.name) {
                names.push(node.name);
            }
        }
        names
    }

    /// Bytes of the intermediate signals a one-call run of `len` samples joins or
    /// computes whole (requested outputs aside), and the nodes that take it whole.
    fn one_call_bytes(&self, len: usize) -> (f64, Vec<&'static str>) {
        let invariant = self.graph.invariant_nodes();
        let kept = self.kept_outputs(&invariant, false);
        let absorbing = self.graph.absorbing_nodes(&invariant);
        let mut bytes = 0.0;
        let mut what: Vec<&'static str> = Vec::new();
        for (i, node) in self.graph.nodes.iter().enumerate() {
            let one_call = !invariant[i] && !absorbing[i];
            if one_call && !what.contains(&node.name) {
                what.push(node.name);
            }
            for (o, info) in node.infos.iter().enumerate() {
                let r = OutputRef { node: i, output: o };
                if (kept[i][o] || one_call) && !self.is_requested(r) {
                    bytes += self.signal_bytes(info, len);
                }
            }
        }
        (bytes, what)
    }

    /// Processes a whole signal from a fresh state (every processor is reset first), as
    /// the AFE's `processSignal`. A chunk-invariant graph runs it in blocks of
    /// [`WHOLE_SIGNAL_BLOCK`] samples, bit-identical to one call and faster (the
    /// intermediate signals stay in cache), and joins each output's blocks; so does a
    /// graph with the AGC, whose first block then holds its seeding time (see
    /// [`Manager::one_call_prefix`]). In a graph with processors that depend on chunk
    /// boundaries (pitch, the maps, gabor, the Hilbert IHC), those get the whole signal
    /// in one call, and the invariant chain below them still runs in blocks (on this
    /// thread).
    pub fn process_signal(&mut self, signal: &[&[f64]]) -> Result<()> {
        self.run_signal(signal, None)
    }

    /// As [`Manager::process_signal`], for a consumer that hands the output on rather
    /// than keeping it (a file written as it comes, `afe bench --discard`): each requested
    /// output computed in blocks (every one in a chunk-invariant graph, those of the
    /// invariant part otherwise) goes to `each_block` block by block, with its reference
    /// (as [`crate::Signal::source`]), instead of being joined, so that it never takes the
    /// whole signal's memory. The signals then show only the other requested outputs.
    pub fn process_signal_streaming(
        &mut self,
        signal: &[&[f64]],
        each_block: &mut BlockSink<'_>,
    ) -> Result<()> {
        self.run_signal(signal, Some(each_block))
    }

    /// [`Manager::process_signal`], streaming the outputs computed in blocks to `stream`
    /// where given.
    fn run_signal(
        &mut self,
        signal: &[&[f64]],
        mut stream: Option<&mut BlockSink<'_>>,
    ) -> Result<()> {
        self.check_chunk(signal)?;
        let len = signal[0].len();
        if len == 0 {
            return Err(Error::InvalidInput("the signal is empty".into()));
        }
        self.reset()?;
        let Some(prefix) = self.graph.one_call_prefix() else {
            self.check_whole_signal(len)?;
            // The nodes that depend on chunk boundaries must see the signal in one call:
            // the invariant part runs in blocks, then those nodes once each (on the
            // workers where there are some), with the processors back in the graph.
            let invariant = self.graph.invariant_nodes();
            self.edit(|m| {
                let shown = m.kept_outputs(&invariant, false);
                let mut whole = m.whole_buffers(&invariant, len, stream.is_some())?;
                // the invariant outputs not joined are handed on, those shown streamed
                let streamed: Vec<Vec<bool>> = (whole.iter().zip(&shown).enumerate())
                    .map(|(i, (acc, shown))| {
                        let each = acc.iter().zip(shown);
                        each.map(|(a, s)| invariant[i] && a.is_none() && *s && stream.is_some())
                            .collect()
                    })
                    .collect();
                let mut each = |r: OutputRef, b: &Block| {
                    if let Some(f) = stream.as_mut() {
                        f(r, b);
                    }
                };
                let ran = m.graph.run_whole(
                    signal,
                    &mut whole,
                    &streamed,
                    &mut each,
                    m.engine.as_mut(),
                    &m.cancel,
                );
                m.whole = whole;
                ran
            })?;
            for (clocks, kept) in self.clocks.iter_mut().zip(&self.whole) {
                for (c, w) in clocks.iter_mut().zip(kept) {
                    c.advance(w.as_ref().map_or(0, |b| b.frames() as u64));
                }
            }
            self.stream_pos += len as u64;
            self.whole_shown = true;
            return Ok(());
        };
        self.run_blocks(BlockInput::Signal(signal, 0), len, prefix, stream)?;
        self.show_since_reset();
        Ok(())
    }

    /// As [`Manager::process_signal`] for a graph that runs in blocks (see
    /// [`Manager::one_call_prefix`]), its input drawn block by block from `next` instead
    /// of held whole: a long file decoded as it goes, its outputs written once into
    /// buffers sized for `samples` input samples per ear (the length where known, else 0:
    /// they then grow as they fill).
    ///
    /// ```
    /// use afe_core::ParamMap;
    /// use afe_graph::Manager;
    /// let x: Vec<f64> = (0..16000).map(|t| (0.05 * t as f64).sin()).collect();
    /// let mut mgr = Manager::new(16000.0, 1)?;
    /// mgr.add_request("innerhaircell", &ParamMap::new())?;
    /// let mut pos = 0;
    /// mgr.process_source(x.len(), &mut |n, out| {
    ///     let end = x.len().min(pos + n);
    ///     out[0].clear();
    ///     out[0].extend_from_slice(&x[pos..end]);
    ///     let got = end - pos;
    ///     pos = end;
    ///     Ok(got)
    /// })?;
    /// assert_eq!(mgr.signals(false)[0].new.frames(), 16000);
    /// # Ok::<(), afe_core::Error>(())
    /// ```
    pub fn process_source(&mut self, samples: usize, next: &mut BlockSource<'_>) -> Result<()> {
        let Some(prefix) = self.graph.one_call_prefix() else {
            return Err(Error::InvalidInput(format!(
                "the whole signal must reach {} in one call, not drawn block by block: \
                 gather it and call process_signal",
                self.per_chunk_nodes().join(", ")
            )));
        };
        self.reset()?;
        let input = BlockInput::source(next, self.ears);
        self.run_blocks(input, samples, prefix, None)?;
        self.show_since_reset();
        Ok(())
    }

    /// Runs `input` through the graph in blocks of [`WHOLE_SIGNAL_BLOCK`] samples (the
    /// first holding at least `prefix`), pipelined, and shows the joined outputs (the
    /// requested ones, or all with [`Manager::set_keep_all`]), sized for `samples` input
    /// samples, or hands each block of them to `stream` where given. The memory limit
    /// is checked before the outputs are sized, or at the first block where `samples` is
    /// 0 (a source of unknown length).
    pub(super) fn run_blocks(
        &mut self,
        input: BlockInput<'_, '_>,
        samples: usize,
        prefix: usize,
        mut stream: Option<&mut BlockSink<'_>>,
    ) -> Result<()> {
        if samples > 0 {
            self.check_whole_signal(samples)?;
        }
        let invariant = vec![true; self.graph.nodes.len()];
        let mut whole = self.whole_buffers(&invariant, samples, stream.is_some())?;
        let streamed: Vec<OutputRef> = match stream {
            Some(_) => self
                .kept_outputs(&invariant, false)
                .iter()
                .enumerate()
                .flat_map(|(node, k)| {
                    k.iter()
                        .enumerate()
                        .filter(|(_, k)| **k)
                        .map(move |(output, _)| OutputRef { node, output })
                })
                .collect(),
            None => Vec::new(),
        };
        // The sequential executor writes the joined outputs in place; the concurrent one
        // double-buffers every output, and each node appends its own to them as it goes
        let lent = match self.engine.as_mut() {
            Some(e) => {
                e.lend_kept(&mut whole, &invariant);
                Vec::new()
            }
            None => self.graph.lend_buffers(&mut whole, &invariant),
        };
        // (a panic in the source or the stream still gives the buffers back; after an
        // error, the chunks still in flight are finished there, and a reset follows)
        let fed = catch_unwind(AssertUnwindSafe(|| {
            self.feed_blocks(input, prefix, &lent, &streamed, &mut stream)
        }));
        let idle = match self.engine.as_mut() {
            Some(e) => e.return_kept(&mut whole),
            None => {
                self.graph.return_buffers(&mut whole, &lent);
                Ok(())
            }
        };
        self.whole = whole;
        let fed = fed.unwrap_or_else(|panic| resume_unwind(panic));
        idle?;
        fed?;
        self.whole_shown = true;
        Ok(())
    }

    /// Shows a whole-signal run's output from its first frame, the first since the reset.
    fn show_since_reset(&mut self) {
        for c in self.clocks.iter_mut().flatten() {
            c.first_since = 0;
            c.first_given = c.given - c.since;
        }
    }

    /// [`Manager::run_blocks`]' loop: submits the blocks and collects them, the `lent`
    /// outputs being written in place.
    fn feed_blocks(
        &mut self,
        mut input: BlockInput<'_, '_>,
        prefix: usize,
        lent: &[OutputRef],
        streamed: &[OutputRef],
        stream: &mut Option<&mut BlockSink<'_>>,
    ) -> Result<()> {
        let mut fed = 0;
        loop {
            if self.cancel.is_cancelled() {
                return Err(Error::Interrupted);
            }
            let part = input.next(WHOLE_SIGNAL_BLOCK.max(prefix.saturating_sub(fed)))?;
            let got = part.first().map_or(0, |p| p.len());
            if got == 0 {
                break;
            }
            if fed == 0 {
                // a first block that holds a long seeding time holds every node's output
                // (checked up front where the length is known; here for a source)
                self.check_whole_signal(got)?;
            }
            fed += got;
            self.graph.seal_lent(lent);
            self.submit_chunk(&part)?;
            if self.in_flight() >= self.pipeline_depth() {
                self.collect_block(streamed, stream)?;
            }
        }
        while self.in_flight() > 0 {
            self.collect_block(streamed, stream)?;
        }
        if fed == 0 {
            return Err(Error::InvalidInput("the signal is empty".into()));
        }
        Ok(())
    }

    /// Collects the oldest block in flight (its joined outputs written in place or
    /// appended by their nodes), and hands those `streamed` to `stream`.
    fn collect_block(
        &mut self,
        streamed: &[OutputRef],
        stream: &mut Option<&mut BlockSink<'_>>,
    ) -> Result<()> {
        self.collect_chunk()?;
        if let Some(f) = stream {
            for &r in streamed {
                if let Some(s) = self.signal(r) {
                    f(r, s.new);
                }
            }
        }
        Ok(())
    }

    /// Empty buffers for the outputs that `process_signal` joins, per node and output,
    /// `None` for the others (reusing the last call's allocations). Those joined block by
    /// block (the `invariant` nodes') are sized for a signal of `samples` samples, so
    /// that each value is written once; the others are moved in whole (see
    /// [`Graph::run_whole`]).
    fn whole_buffers(
        &mut self,
        invariant: &[bool],
        samples: usize,
        stream: bool,
    ) -> Result<Vec<Vec<Option<Block>>>> {
        let kept = self.kept_outputs(invariant, stream);
        let fs = self.fs;
        let mut whole = std::mem::take(&mut self.whole);
        whole.resize_with(kept.len(), Vec::new);
        for (((acc, keep), node), &blocks) in whole
            .iter_mut()
            .zip(&kept)
            .zip(&self.graph.nodes)
            .zip(invariant)
        {
            acc.resize_with(keep.len(), || None);
            for ((slot, &k), info) in acc.iter_mut().zip(keep).zip(&node.infos) {
                match (k, slot.as_mut()) {
                    (false, _) => *slot = None,
                    (true, Some(b)) if b.width() == info.width() => b.clear(),
                    (true, _) => *slot = Some(Block::new(info.width())),
                }
                if let (true, Some(b)) = (blocks, slot.as_mut()) {
                    reserve(b, samples, info.fs_hz / fs, node.name)?;
                }
            }
        }
        Ok(whole)
    }

    /// Which outputs `process_signal` joins, per node and output: the requested ones
    /// (every one with [`Manager::set_keep_all`]) and, in a graph with per-chunk nodes
    /// (`invariant` false), the inputs of those that do not absorb blocks. The rest (the full-rate filterbank and
    /// IHC signals are 2.8 MB per second and channel pair) is never joined.
    fn kept_outputs(&self, invariant: &[bool], stream: bool) -> Vec<Vec<bool>> {
        let nodes = &self.graph.nodes;
        // streamed outputs are not joined for show
        let shown = |i: usize| !(stream && invariant[i]);
        let mut kept: Vec<Vec<bool>> = nodes
            .iter()
            .enumerate()
            .map(|(i, n)| vec![self.keep_all && i > 0 && shown(i); n.outputs.len()])
            .collect();
        for r in self.requests.iter().flatten().flat_map(|r| &r.outputs) {
            kept[r.node][r.output] = shown(r.node);
        }
        let absorbing = self.graph.absorbing_nodes(invariant);
        let joined = invariant.iter().zip(&absorbing).map(|(i, a)| !i && !a);
        for (node, _) in nodes.iter().zip(joined).filter(|(_, j)| *j) {
            for p in &node.parents {
                kept[p.node][p.output] = true;
            }
        }
        kept
    }

    /// After [`Manager::process_signal`], moves the joined output `r` out of the manager
    /// (it then no longer appears among the signals) instead of copying a signal that
    /// may be hundreds of MB; `None` after a chunk or edit, or when already taken.
    pub fn take_whole(&mut self, r: OutputRef) -> Option<Block> {
        if !self.whole_shown {
            return None;
        }
        self.whole.get_mut(r.node)?.get_mut(r.output)?.take()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::block_input::slice_source;
    use afe_core::ParamMap;
    use serde_json::json;

    /// A whole signal that processors take at once (the Hilbert IHC) is refused before
    /// anything is allocated when its intermediate signals would pass the limit, naming
    /// the processor; a graph that runs in blocks (here the AGC) is never refused.
    #[test]
    fn a_whole_signal_too_large_for_one_call_is_refused_up_front() {
        let fs = 16000.0;
        let p: ParamMap = [("ihc_method".to_string(), json!("hilbert"))]
            .into_iter()
            .collect();
        let mut m = Manager::new(fs, 2).expect("manager");
        m.add_request("ratemap", &p).expect("request");
        // joined filterbank and IHC output, 31 channels, both ears: 15.9 MB per second
        assert!(m.check_whole_signal(60 * 16000).is_ok());
        let long = 200 * 16000;
        match m.check_whole_signal(long) {
            Err(Error::WholeSignalTooLarge {
                need_mb,
                limit_mb,
                what,
                ..
            }) => {
                assert_eq!(
                    need_mb,
                    (long as f64 * 4.0 * 31.0 * 8.0 / 1e6).ceil() as u64
                );
                assert_eq!(limit_mb, WHOLE_SIGNAL_LIMIT_MB);
                assert!(what.starts_with("innerhaircell"), "{what}");
            }
            other => panic!("expected the limit, got {other:?}"),
        }
        let x = vec![0.1; long];
        assert!(matches!(
            m.process_signal(&[&x, &x]),
            Err(Error::WholeSignalTooLarge { .. })
        ));
        let agc: ParamMap = [("pp_bNormalizeRMS".to_string(), json!(true))]
            .into_iter()
            .collect();
        let mut m = Manager::new(fs, 2).expect("manager");
        m.add_request("ratemap", &agc).expect("request");
        assert!(m.check_whole_signal(100 * long).is_ok());
    }

    /// A binaural manager on `threads` worker threads with `requests` at their defaults.
    fn binaural(fs: f64, threads: usize, requests: &[&str]) -> Manager {
        let mut m = Manager::with_threads(fs, 2, threads).expect("manager");
        for r in requests {
            m.add_request(r, &ParamMap::new()).expect("request");
        }
        m
    }

    /// `len` samples of a tone (`w` radians per sample) whose amplitude swells from 1 to 2
    /// over every `period` samples: blocks differ from one another.
    fn swelling_tone(len: usize, w: f64, period: usize) -> Vec<f64> {
        (0..len)
            .map(|t| (w * t as f64).sin() * (1.0 + (t % period) as f64 / period as f64))
            .collect()
    }

    /// The values' bit patterns, to compare blocks bit for bit.
    fn bits(b: &Block) -> Vec<u64> {
        b.as_slice().iter().map(|v| v.to_bits()).collect()
    }

    /// A cancelled manager's whole-signal calls stop with `Interrupted` (in blocks, in
    /// one call, on either executor) until its token is cleared; a manager that shares
    /// the token stops too, one with its own runs on.
    #[test]
    fn a_cancelled_token_stops_its_managers_and_no_other() {
        let fs = 16000.0;
        let x = swelling_tone(3 * WHOLE_SIGNAL_BLOCK + 77, 0.03, 500);
        for requests in [&["ratemap", "ild"][..], &["pitch"][..]] {
            for threads in [0, 2] {
                let mut stopped = binaural(fs, threads, requests);
                let mut sharing = binaural(fs, threads, requests);
                sharing.set_cancel_token(stopped.cancel_token().clone());
                let mut other = binaural(fs, threads, requests);
                stopped.cancel_token().cancel();
                let case = format!("{requests:?} on {threads} threads");
                for m in [&mut stopped, &mut sharing] {
                    let e = m.process_signal(&[&x, &x]).expect_err(&case);
                    assert!(matches!(e, Error::Interrupted), "{case}: {e}");
                }
                other.process_signal(&[&x, &x]).expect(&case);
                stopped.cancel_token().clear();
                stopped.process_signal(&[&x, &x]).expect(&case);
                let (a, b) = (stopped.signals(false), other.signals(false));
                assert_eq!(a.len(), b.len());
                for (a, b) in a.iter().zip(&b) {
                    assert_eq!(bits(a.new), bits(b.new), "{case}: {}", a.key());
                }
            }
        }
    }

    /// The sequential executor writes a whole signal's joined outputs in place, block
    /// after block, into the buffers sized for the signal: the outputs' own blocks are
    /// never used (they would hold a block each, copied on). The values are those of a
    /// run with the concurrent executor. Both graphs join every intermediate signal.
    #[test]
    fn whole_signals_are_written_in_place_not_copied() {
        let fs = 16000.0;
        let x = swelling_tone(3 * WHOLE_SIGNAL_BLOCK + 77, 0.03, 500);
        for requests in [&["ratemap", "ild"][..], &["ratemap", "onsetMap"][..]] {
            let run = |threads| {
                let mut m = binaural(fs, threads, requests);
                m.set_keep_all(true);
                m.process_signal(&[&x, &x]).expect("process");
                m
            };
            let (sequential, concurrent) = (run(0), run(2));
            let invariant = sequential.graph.invariant_nodes();
            let mut joined = 0;
            for (s, c) in sequential
                .signals(true)
                .iter()
                .zip(concurrent.signals(true))
            {
                assert_eq!(s.key(), c.key());
                assert_eq!(bits(s.new), bits(c.new), "{requests:?}: {}", s.key());
                if s.source.node > 0 && invariant[s.source.node] {
                    let own = &sequential.graph.nodes[s.source.node].outputs[s.source.output];
                    assert_eq!(own.room(), 0, "{requests:?}: {} was copied", s.key());
                    joined += 1;
                }
            }
            assert!(joined >= 6, "{requests:?}: {joined} joined in blocks");
        }
    }

    /// On the concurrent executor, each node keeps its own joined output: the caller
    /// copies none of them, and a node that no processor in the pool reads (`ratemap`,
    /// `ild`) writes straight into its buffer, never into its slots, while one that is
    /// read (the filterbank, the hair cell) computes into its slots and appends. Same bits
    /// as on one thread, output by output.
    #[test]
    fn the_concurrent_executor_keeps_whole_outputs_without_the_callers_copy() {
        let fs = 16000.0;
        let x = swelling_tone(4 * WHOLE_SIGNAL_BLOCK + 5, 0.03, 500);
        let run = |threads| {
            let mut m = binaural(fs, threads, &["ratemap", "ild"]);
            m.set_keep_all(true);
            m.process_signal(&[&x, &x]).expect("process");
            m
        };
        let (sequential, mut concurrent) = (run(0), run(2));
        let (s, c) = (sequential.signals(true), concurrent.signals(true));
        assert_eq!(s.len(), c.len());
        let mut nodes = Vec::new();
        for (s, c) in s.iter().zip(&c) {
            assert_eq!(s.key(), c.key());
            assert_eq!(bits(s.new), bits(c.new), "{}", s.key());
            assert!(s.new.frames() > 20, "{}", s.key());
            if c.source.node > 0 {
                nodes.push((c.source.node, c.name));
            }
        }
        let engine = concurrent.engine.as_mut().expect("engine");
        engine.quiesce().expect("idle");
        let mut in_place = Vec::new();
        for (node, name) in nodes {
            let rooms = engine.rooms(node);
            assert!(
                rooms.iter().all(|r| r.2 == 0),
                "{name}: the caller copied it"
            );
            if rooms.iter().all(|r| r.0 == 0 && r.1 == 0) {
                in_place.push(name);
            }
        }
        in_place.sort_unstable();
        in_place.dedup();
        assert_eq!(in_place, ["ild", "ratemap"]);
    }

    /// A source that panics mid-signal leaves no output lent to the concurrent executor's
    /// nodes: after the panic and a reset, chunks give every frame again, as on one thread,
    /// and so does a whole signal after them.
    #[test]
    fn a_panicking_source_gives_the_lent_outputs_back() {
        let fs = 16000.0;
        let x = swelling_tone(6 * WHOLE_SIGNAL_BLOCK, 0.03, 500);
        let after = |threads| {
            let mut m = binaural(fs, threads, &["ratemap", "ild"]);
            let mut reads = 0;
            let panicked = std::panic::catch_unwind(AssertUnwindSafe(|| {
                let mut inner = slice_source(&x, WHOLE_SIGNAL_BLOCK);
                m.process_source(x.len(), &mut |n, out| {
                    reads += 1;
                    assert!(reads < 3, "a source failing on its third read");
                    inner(n, out)
                })
            }));
            assert!(panicked.is_err());
            m.reset().expect("reset");
            let mut frames = 0;
            for part in x.chunks(1600) {
                m.process_chunk(&[part, part]).expect("chunk");
                frames += m
                    .signals(false)
                    .iter()
                    .map(|s| s.new.frames())
                    .sum::<usize>();
            }
            m.process_signal(&[&x, &x]).expect("process");
            let whole: Vec<Vec<u64>> = m.signals(false).iter().map(|s| bits(s.new)).collect();
            (frames, whole)
        };
        let (sequential, concurrent) = (after(0), after(2));
        assert!(sequential.0 > 100, "{} frames", sequential.0);
        assert_eq!(concurrent, sequential);
    }

    /// A whole signal drawn block by block from a source (in short reads, with and
    /// without its length known) gives `process_signal`'s outputs bit for bit, written
    /// in place; so does a graph with the AGC, whose first block must hold its seeding
    /// time. A graph with per-chunk nodes and an empty source are refused.
    #[test]
    fn a_signal_drawn_from_a_source_gives_the_signal_in_memorys_output() {
        let fs = 16000.0;
        let x = swelling_tone(5 * WHOLE_SIGNAL_BLOCK + 31, 0.04, 600);
        let agc: ParamMap = [("pp_bNormalizeRMS".to_string(), json!(1))]
            .into_iter()
            .collect();
        for (p, hint) in [(ParamMap::new(), x.len()), (agc, 0)] {
            let fresh = || {
                let mut m = Manager::new(fs, 2).expect("manager");
                for r in ["ratemap", "ild"] {
                    m.add_request(r, &p).expect("request");
                }
                m.set_keep_all(true);
                m
            };
            let mut whole = fresh();
            whole.process_signal(&[&x, &x]).expect("process");
            let mut drawn = fresh();
            drawn
                .process_source(hint, &mut slice_source(&x, 700))
                .expect("drawn");
            let (w, d) = (whole.signals(true), drawn.signals(true));
            assert_eq!(w.len(), d.len());
            for (w, d) in w.iter().zip(&d) {
                assert_eq!(w.key(), d.key());
                assert_eq!(bits(w.new), bits(d.new), "hint {hint}: {}", d.key());
                let own = &drawn.graph.nodes[d.source.node].outputs[d.source.output];
                assert_eq!(own.room(), 0, "hint {hint}: {} was copied", d.key());
            }
        }
        // onsetMap takes its input whole; pitch absorbs it block by block, but its
        // frames still depend on the chunking
        for request in ["onsetMap", "pitch"] {
            let mut per_chunk = binaural(fs, 0, &[request]);
            let e = per_chunk
                .process_source(0, &mut |_, _| Ok(0))
                .expect_err("per-chunk");
            let e = e.to_string();
            let named = format!("must reach {request} in one call");
            assert!(
                e.contains(&named) && e.contains("call process_signal"),
                "{e}"
            );
        }
        let mut empty = binaural(fs, 0, &["ratemap"]);
        let e = empty
            .process_source(0, &mut |_, _| Ok(0))
            .expect_err("empty");
        assert!(e.to_string().contains("the signal is empty"), "{e}");
    }

    /// A streamed whole-signal call hands on, block by block, exactly the requested
    /// outputs computed in blocks, and they join to `process_signal`'s bit for bit; the
    /// others are shown as after `process_signal` (both executors; graphs with per-chunk
    /// nodes, with one that absorbs blocks, and a chunk-invariant one).
    #[test]
    fn a_streamed_whole_signal_hands_on_the_blocks_it_does_not_join() {
        let fs = 16000.0;
        let x = swelling_tone(3 * WHOLE_SIGNAL_BLOCK + 123, 0.05, 700);
        let y: Vec<f64> = x.iter().map(|v| 0.5 * v).collect();
        for threads in [0, 2] {
            for (requests, streamed) in [
                (&["ratemap", "onsetMap"][..], &["ratemap"][..]),
                // pitch absorbs the autocorrelation's blocks, which are not handed on
                (&["pitch", "ratemap"][..], &["ratemap"][..]),
                (&["ratemap", "ild"][..], &["ratemap", "ild"][..]),
            ] {
                let manager = || binaural(fs, threads, requests);
                let mut whole = manager();
                whole.process_signal(&[&x, &y]).expect("process");
                let mut m = manager();
                let mut blocks: Vec<(OutputRef, Block)> = Vec::new();
                m.process_signal_streaming(&[&x, &y], &mut |r, b| match blocks
                    .iter_mut()
                    .find(|(s, _)| *s == r)
                {
                    Some((_, acc)) => acc.extend_from(b),
                    None => blocks.push((r, b.clone())),
                })
                .expect("process");
                let shown = m.signals(false);
                let what = format!("{requests:?}, threads {threads}");
                assert_eq!(
                    blocks.len() + shown.len(),
                    whole.signals(false).len(),
                    "{what}"
                );
                for s in whole.signals(false) {
                    let kept = shown.iter().find(|k| k.source == s.source);
                    let got = blocks.iter().find(|(r, _)| *r == s.source);
                    let data = match (kept, got) {
                        (Some(k), None) => k.new,
                        (None, Some((_, b))) => b,
                        _ => panic!(
                            "{what}: {} shown {} and streamed {}",
                            s.name,
                            kept.is_some(),
                            got.is_some()
                        ),
                    };
                    assert_eq!(
                        got.is_some(),
                        streamed.contains(&s.name),
                        "{what}: {}",
                        s.name
                    );
                    assert!(s.new.frames() > 0, "{what}: {}", s.name);
                    assert_eq!(bits(data), bits(s.new), "{what}: {}", s.name);
                }
            }
        }
    }
}
