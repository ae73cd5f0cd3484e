//! The streaming path: a chunk checked, then run on the sequential executor or
//! submitted to the concurrent one and collected, and the buffers sized before the first.

use super::*;

impl Manager {
    /// Checks that an input of `channels` channels is one this manager was made for.
    pub fn check_channels(&self, channels: usize) -> Result<()> {
        if channels == self.ears {
            return Ok(());
        }
        Err(Error::InvalidInput(format!(
            "got {channels} channel(s), but this manager was made for {} ({})",
            self.ears,
            if self.ears == 2 {
                "left, right"
            } else {
                "mono"
            }
        )))
    }

    pub(super) fn check_chunk(&self, chunk: &[&[f64]]) -> Result<()> {
        self.check_channels(chunk.len())?;
        if chunk.iter().any(|c| c.len() != chunk[0].len()) {
            return Err(Error::InvalidInput(format!(
                "left and right have different lengths ({} and {} samples)",
                chunk[0].len(),
                chunk[chunk.len() - 1].len()
            )));
        }
        let names = ["left", "right"];
        let (node, gain) = self.graph.largest_input_gain();
        let limit = MAX_AMPLITUDE / gain;
        for (e, ear) in chunk.iter().enumerate() {
            if let Some(i) = ear.iter().position(|v| v.is_nan() || v.abs() > limit) {
                let which = if self.ears == 2 { names[e] } else { "mono" };
                let at = self.position + i as u64;
                return Err(Error::InvalidInput(if ear[i].is_finite() && gain > 1.0 {
                    format!(
                        "sample {at} of the {which} channel is {:e}: '{node}' raises it by up \
                         to {gain:e} (its level scaling, pre-emphasis and middle-ear filter), \
                         beyond ±{MAX_AMPLITUDE:e}, where the processing overflows: scale the \
                         input down (full scale is 1.0) or lower that gain (pp_refSPLdB)",
                        ear[i]
                    )
                } else if ear[i].is_finite() {
                    format!(
                        "sample {at} of the {which} channel is {:e}: beyond ±{MAX_AMPLITUDE:e} \
                         the processing overflows (full scale is 1.0: scale the input)",
                        ear[i]
                    )
                } else {
                    format!(
                        "sample {at} of the {which} channel is {} (the input must be finite)",
                        ear[i]
                    )
                }));
            }
        }
        Ok(())
    }

    /// Processes the next chunk of a stream (one slice per ear, equal lengths), carrying
    /// every processor's state over from the previous chunk. The new output of every
    /// signal is then available through [`Manager::signals`].
    ///
    /// ```
    /// use afe_graph::Manager;
    /// let mut mgr = Manager::new(16000.0, 1)?;
    /// let h = mgr.add_request("ratemap", &Default::default())?;
    /// let x = vec![0.1; 1600];
    /// let mut frames = 0;
    /// for chunk in x.chunks(160) {
    ///     // 10-ms chunks; the 20-ms window needs two of them before the first frame
    ///     mgr.process_chunk(&[chunk])?;
    ///     frames += mgr.request_signals(h)?[0].new.frames();
    /// }
    /// assert_eq!(frames, 9);
    /// # Ok::<(), afe_core::Error>(())
    /// ```
    pub fn process_chunk(&mut self, chunk: &[&[f64]]) -> Result<()> {
        while self.in_flight() > 0 {
            self.collect_chunk()?;
        }
        let len = chunk.first().map_or(0, |c| c.len());
        if len > LONG_CHUNK && self.is_chunk_invariant() {
            return self.process_long_chunk(chunk);
        }
        self.submit_chunk(chunk)?;
        self.collect_chunk()
    }

    /// A long chunk through a chunk-invariant graph, in blocks (bit-identical), keeping
    /// only the outputs shown ([`Manager::set_keep_all`]): its intermediate signals are
    /// never held whole, so memory does not grow with the chunk's length.
    fn process_long_chunk(&mut self, chunk: &[&[f64]]) -> Result<()> {
        self.check_chunk(chunk)?;
        let before: Vec<Vec<(u64, u64)>> = self
            .clocks
            .iter()
            .map(|c| c.iter().map(|c| (c.since, c.given)).collect())
            .collect();
        let len = chunk[0].len();
        self.run_blocks(BlockInput::Signal(chunk, 0), len, 0, None)?;
        // the chunk's first frame is the first of its first block
        for (clocks, before) in self.clocks.iter_mut().zip(before) {
            for (c, (since, given)) in clocks.iter_mut().zip(before) {
                c.first_since = since;
                c.first_given = given;
            }
        }
        Ok(())
    }

    /// Sizes every output block and every processor's buffers for chunks of up to
    /// `max_chunk` samples before the first chunk, so that no chunk up to that size
    /// allocates on the audio path, the first ones included: silent chunks of that size
    /// run through the processors on this thread (at least two, then until every output
    /// has had frames twice, at most [`PREPARE_SECONDS_MAX`] of audio), which are then
    /// reset. Only before the first chunk (or after [`Manager::reset`]); a request added
    /// later is sized by its first chunks.
    pub fn prepare(&mut self, max_chunk: usize) -> Result<()> {
        if self.position != 0 {
            return Err(Error::InvalidInput(
                "prepare sizes the buffers before the stream starts: call it before the first chunk or after reset".into(),
            ));
        }
        if !(1..=MAX_PREPARED_CHUNK).contains(&max_chunk) {
            return Err(Error::InvalidInput(format!(
                "prepare({max_chunk}): give the largest chunk, 1 to {MAX_PREPARED_CHUNK} samples"
            )));
        }
        let silence = vec![0.0; max_chunk];
        // at least two chunks (the second also meets the rows the first one left for later
        // frames), and until every output has had frames twice: a window longer than two
        // chunks gives its first frame later
        let most = (PREPARE_SECONDS_MAX * self.fs) as usize / max_chunk + 2;
        self.edit(|m| {
            let chunk: Vec<&[f64]> = (0..m.ears).map(|_| silence.as_slice()).collect();
            let mut outputs_seen: Vec<Vec<u8>> = m
                .graph
                .nodes
                .iter()
                .map(|n| vec![0; n.outputs.len()])
                .collect();
            for k in 0..most {
                m.graph.load_input(&chunk);
                m.graph.run_sequential();
                for (seen, node) in outputs_seen.iter_mut().zip(&m.graph.nodes) {
                    for (s, block) in seen.iter_mut().zip(&node.outputs) {
                        *s = s.saturating_add(u8::from(!block.is_empty()));
                    }
                }
                if k >= 1 && outputs_seen.iter().flatten().all(|s| *s >= 2) {
                    break;
                }
            }
            m.graph.reset();
            Ok(())
        })
    }

    /// Starts processing the next chunk without waiting for it: with the concurrent
    /// scheduler, chunk k+1 enters the graph while chunk k is still in its deeper nodes.
    /// Collect each chunk's output, in order, with [`Manager::collect_chunk`]; keep at most
    /// [`Manager::pipeline_depth`] chunks in flight (submitting more is an error).
    ///
    /// ```
    /// use afe_graph::Manager;
    /// let mut mgr = Manager::with_threads(16000.0, 2, 2)?;
    /// mgr.add_request("ild", &Default::default())?;
    /// let (l, r) = (vec![0.1; 1600], vec![0.2; 1600]);
    /// let mut frames = 0;
    /// for (a, b) in l.chunks(160).zip(r.chunks(160)) {
    ///     mgr.submit_chunk(&[a, b])?;
    ///     if mgr.in_flight() == mgr.pipeline_depth() {
    ///         mgr.collect_chunk()?;
    ///         frames += mgr.signals(false)[0].new.frames();
    ///     }
    /// }
    /// while mgr.in_flight() > 0 {
    ///     mgr.collect_chunk()?;
    ///     frames += mgr.signals(false)[0].new.frames();
    /// }
    /// assert_eq!(frames, 9);
    /// # Ok::<(), afe_core::Error>(())
    /// ```
    pub fn submit_chunk(&mut self, chunk: &[&[f64]]) -> Result<()> {
        self.check_chunk(chunk)?;
        self.whole_shown = false;
        let len = chunk.first().map_or(0, |c| c.len() as u64);
        match self.engine.as_mut() {
            Some(e) => {
                e.submit(chunk)?;
                self.position += len;
                self.stream_pos += len;
                Ok(())
            }
            None => {
                if self.pending > 0 {
                    return Err(Error::InvalidInput(
                        "the sequential executor holds one chunk: collect it before submitting the next".into(),
                    ));
                }
                self.graph.load_input(chunk);
                self.graph.run_sequential();
                self.pending = 1;
                self.position += len;
                self.stream_pos += len;
                Ok(())
            }
        }
    }

    /// Waits for the oldest submitted chunk and makes its output the one
    /// [`Manager::signals`] shows.
    pub fn collect_chunk(&mut self) -> Result<()> {
        match self.engine.as_mut() {
            Some(e) => e.collect().map(|_| ())?,
            None if self.pending > 0 => self.pending = 0,
            None => return Err(Error::Scheduler("no chunk in flight to collect".into())),
        }
        self.tick();
        Ok(())
    }

    /// Chunks submitted and not yet collected.
    pub fn in_flight(&self) -> usize {
        match &self.engine {
            Some(e) => e.in_flight() as usize,
            None => self.pending as usize,
        }
    }

    /// How many chunks may usefully be in flight: 1 for the sequential executor, 2 for
    /// the concurrent one (each node double-buffers its output).
    pub fn pipeline_depth(&self) -> usize {
        if self.engine.is_some() {
            2
        } else {
            1
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_manager_moves_between_threads_mid_stream_and_bounds_chunks_in_flight() {
        let mut m = Manager::with_threads(16000.0, 2, 2).expect("valid");
        m.set_stall_timeout(std::time::Duration::from_secs(10));
        let h = m.add_request("ild", &ParamMap::new()).expect("ok");
        let x = vec![0.1; 1600];
        m.submit_chunk(&[&x, &x]).expect("first");
        m.submit_chunk(&[&x, &x]).expect("second");
        let e = m.submit_chunk(&[&x, &x]).expect_err("a third in flight");
        assert!(e.to_string().contains("collect one"), "{e}");
        // another thread collects what this one submitted, then goes on streaming
        let m = std::thread::spawn(move || {
            m.collect_chunk().expect("collect on another thread");
            m.collect_chunk().expect("collect on another thread");
            m.process_chunk(&[&x, &x]).expect("stream on");
            m
        })
        .join()
        .expect("thread");
        assert_eq!(m.request_signals(h).expect("ild")[0].new.frames(), 10);
    }
}
