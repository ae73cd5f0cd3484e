//! The signals a manager shows: each output with its description, its new block and
//! where its first frame stands, by request or all at once.

use super::*;

/// One output signal of the graph, as seen after the last processed chunk.
#[derive(Debug, Clone, Copy)]
pub struct Signal<'a> {
    /// Index of the first new frame among all the frames this output has given (it
    /// keeps counting across `reset` and `modify_parameter`).
    pub first_frame: u64,
    /// Time of the first new frame in seconds from the start of the stream: an output
    /// whose framing (re)started at input sample `s` (when it was placed, reset or
    /// rebuilt by `modify_parameter`) has its frame `k` at `s / fs + k / fs_hz`, the
    /// AFE's time axis (first frame at the start).
    pub first_time_s: f64,
    /// Name of the signal: the request's, e.g. `ratemap`, or the output's own where a
    /// processor has several (`precedence_itd`, `precedence_ild`, `precedence_cc`).
    pub name: &'static str,
    /// 1-based instance among the signals of the same name (requests with different
    /// parameters make several instances).
    pub instance: usize,
    /// Ear of the signal.
    pub channel: Channel,
    /// Rate, channel centre frequencies and lags.
    pub info: &'a SignalInfo,
    /// The new values computed by the last `process_chunk` / `process_signal`,
    /// time-major (`[frame][channel]` or `[frame][channel][lag]`).
    pub new: &'a Block,
    /// Where the signal lives in the graph.
    pub source: OutputRef,
}

impl Signal<'_> {
    /// The output name used by the CLI and Python: `<name>_<channel>`, or
    /// `<name>_<k>_<channel>` for the k-th instance (k ≥ 2), as in the AFE oracle.
    pub fn key(&self) -> String {
        if self.instance > 1 {
            format!("{}_{}_{}", self.name, self.instance, self.channel.as_str())
        } else {
            format!("{}_{}", self.name, self.channel.as_str())
        }
    }
}

impl Manager {
    /// The output signals of a request: one per ear for per-ear representations, one
    /// (`mono`) for binaural cues.
    ///
    /// ```
    /// use afe_graph::Manager;
    /// let mut mgr = Manager::new(16000.0, 2)?;
    /// let h = mgr.add_request("crosscorrelation", &Default::default())?;
    /// mgr.process_signal(&[&[0.1; 800], &[0.2; 800]])?;
    /// let cc = &mgr.request_signals(h)?[0];
    /// assert_eq!(cc.key(), "crosscorrelation_mono");
    /// assert_eq!(cc.info.lags_s().len(), 37); // ±ceil(1.1 ms · 16 kHz) lags
    /// assert_eq!(cc.info.cf_hz().len(), 31);
    /// assert_eq!(cc.new.width(), 31 * 37); // [frame][channel][lag]
    /// # Ok::<(), afe_core::Error>(())
    /// ```
    pub fn request_signals(&self, handle: RequestHandle) -> Result<Vec<Signal<'_>>> {
        let req = self
            .requests
            .get(handle.0)
            .and_then(Option::as_ref)
            .ok_or(Error::UnknownHandle(handle.0))?;
        Ok(req.outputs.iter().filter_map(|r| self.signal(*r)).collect())
    }

    /// Output `k` of request `handle`, as [`Manager::request_signals`] lists them, without
    /// allocating (for the audio path); `None` past the last one or for an unknown handle.
    pub fn request_signal(&self, handle: RequestHandle, k: usize) -> Option<Signal<'_>> {
        let req = self.requests.get(handle.0)?.as_ref()?;
        self.signal(*req.outputs.get(k)?)
    }

    /// The parameters every processor of request `handle`'s chain runs with, defaults
    /// included (the AFE's `getParameterSummary`): e.g. for `ild`, the `ild_*`, `ihc_*`,
    /// `fb_*` and `pp_*` values.
    ///
    /// ```
    /// use afe_graph::Manager;
    /// let mut mgr = Manager::new(16000.0, 2)?;
    /// let params = [("fb_nChannels".to_string(), serde_json::json!(8))].into_iter().collect();
    /// let h = mgr.add_request("ild", &params)?;
    /// let used = mgr.request_parameters(h)?;
    /// assert_eq!(used["fb_nChannels"], 8);
    /// assert_eq!(used["ild_wSizeSec"], 0.02);
    /// assert_eq!(used["ihc_method"], "dau");
    /// # Ok::<(), afe_core::Error>(())
    /// ```
    pub fn request_parameters(&self, handle: RequestHandle) -> Result<ParamMap> {
        let req = self
            .requests
            .get(handle.0)
            .and_then(Option::as_ref)
            .ok_or(Error::UnknownHandle(handle.0))?;
        let mut used = ParamMap::new();
        for (_, params) in self.chain_from(req.outputs.iter().map(|r| r.node)) {
            used.extend(params.iter().map(|(k, v)| (k.clone(), v.clone())));
        }
        Ok(used)
    }

    /// The processors signal `r` is computed through, itself first and then its
    /// ancestors nearest first: each one's request name and effective parameters.
    pub fn signal_chain(&self, r: OutputRef) -> Vec<(&'static str, &ParamMap)> {
        self.chain_from([r.node])
    }

    /// `start` and every node above them, breadth first, each once (the input node,
    /// which has no parameters, left out).
    fn chain_from(&self, start: impl IntoIterator<Item = usize>) -> Vec<(&'static str, &ParamMap)> {
        let mut todo: std::collections::VecDeque<usize> = start.into_iter().collect();
        let mut seen = std::collections::HashSet::new();
        let mut chain = Vec::new();
        while let Some(n) = todo.pop_front() {
            if n == 0 || !seen.insert(n) {
                continue;
            }
            let node = &self.graph.nodes[n];
            chain.push((node.name, &node.params));
            todo.extend(node.parents.iter().map(|p| p.node));
        }
        chain
    }

    /// Signals of the graph: the requested ones, or (`all`) every processor output,
    /// including intermediate ones (time, filterbank, innerhaircell, ...), which are
    /// there only with [`Manager::set_keep_all`] on.
    pub fn signals(&self, all: bool) -> Vec<Signal<'_>> {
        let mut refs: Vec<OutputRef> = if all {
            self.graph
                .nodes
                .iter()
                .enumerate()
                .skip(1)
                .flat_map(|(node, n)| {
                    n.infos
                        .iter()
                        .enumerate()
                        .filter(|(_, info)| !info.feedback)
                        .map(move |(output, _)| OutputRef { node, output })
                })
                .collect()
        } else {
            self.requests
                .iter()
                .flatten()
                .flat_map(|r| r.outputs.clone())
                .collect()
        };
        let mut seen = std::collections::HashSet::new();
        refs.retain(|r| seen.insert(*r));
        refs.into_iter().filter_map(|r| self.signal(r)).collect()
    }

    /// Output `r`'s signal; `None` for an intermediate one not kept (see
    /// [`Manager::set_keep_all`]).
    pub(super) fn signal(&self, r: OutputRef) -> Option<Signal<'_>> {
        let node = &self.graph.nodes[r.node];
        let clock = self
            .clocks
            .get(r.node)
            .and_then(|c| c.get(r.output))
            .copied()
            .unwrap_or_default();
        let info = &node.infos[r.output];
        Some(Signal {
            first_frame: clock.first_given,
            first_time_s: clock.start as f64 / self.fs + clock.first_since as f64 / info.fs_hz,
            name: node.infos[r.output].name.unwrap_or(node.name),
            instance: node.instance,
            channel: node.channels[r.output],
            info: &node.infos[r.output],
            new: match (self.whole_shown, &self.engine) {
                (true, _) => self.whole[r.node][r.output].as_ref()?,
                (false, _) if !self.is_read(r) => return None,
                (false, Some(e)) => e.block(r)?,
                (false, None) => &node.outputs[r.output],
            },
            source: r,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// A processor with several outputs names each (the AFE oracle's names).
    #[test]
    fn multi_output_processors_name_their_outputs() {
        let mut m = Manager::new(16000.0, 2).expect("manager");
        let h = m.add_request("precedence", &ParamMap::new()).expect("ok");
        let left = vec![0.1; 1600];
        m.process_signal(&[&left, &left]).expect("ok");
        let keys = output_keys(&m, h);
        assert_eq!(
            keys,
            [
                "precedence_itd_mono",
                "precedence_ild_mono",
                "precedence_cc_mono"
            ]
        );
    }

    /// With `trm_minValuedB` an onset map reads the ratemap beside its onset strength: the
    /// ratemap is the shared one, and a level no frame reaches empties the map.
    #[test]
    fn a_map_reads_the_ratemap_beside_its_strength() {
        let mut m = Manager::new(16000.0, 2).expect("valid");
        let plain = m.add_request("onsetMap", &ParamMap::new()).expect("ok");
        let before = m.processor_count();
        let gated = m
            .add_request("onsetMap", &params(&[("trm_minValuedB", json!(200))]))
            .expect("ratemap wired");
        assert_eq!(m.processor_count(), before + 2, "one new map per ear");
        let map = m.request_signals(gated).expect("ok")[0].source.node;
        let strength = m.request_signals(plain).expect("ok")[0].source.node;
        let parents: Vec<&str> = m.graph.nodes[map]
            .parents
            .iter()
            .map(|p| m.graph.nodes[p.node].name)
            .collect();
        assert_eq!(parents, ["onsetStrength", "ratemap"]);
        assert_eq!(
            m.graph.nodes[map].parents[0].node,
            m.graph.nodes[strength].parents[0].node
        );
        // noise bursts of 0.1 s every 0.3 s: clear onsets
        let mut state = 1u64;
        let x: Vec<f64> = (0..16000)
            .map(|t| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
                let noise = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                if t % 4800 < 1600 {
                    noise
                } else {
                    0.0
                }
            })
            .collect();
        m.process_signal(&[&x, &x]).expect("process");
        let ones = |h| -> f64 {
            m.request_signals(h).expect("ok")[0]
                .new
                .as_slice()
                .iter()
                .sum()
        };
        assert!(ones(plain) > 0.0, "the bursts have onsets");
        assert_eq!(ones(gated), 0.0, "no ratemap frame reaches 200 dB");
    }
}
