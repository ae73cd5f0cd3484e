//! Placing, removing and editing requests between chunks: each change applied with
//! the pool quiesced, the nodes no request reads any more pruned.

use super::*;

impl Manager {
    /// Applies a change to the graph between chunks: the pool finishes what is in flight,
    /// hands the processors back, and gets the edited graph (unchanged nodes keep their
    /// state; everything is built and freed on this thread).
    pub(super) fn edit<R>(&mut self, f: impl FnOnce(&mut Self) -> Result<R>) -> Result<R> {
        if let Some(e) = self.engine.as_mut() {
            e.quiesce()?;
            e.uninstall(&mut self.graph);
        }
        self.pending = 0;
        self.whole_shown = false;
        self.graph.context.started_s = (self.stream_pos - self.reset_pos) as f64 / self.fs;
        let r = f(self);
        if let Some(e) = self.engine.as_mut() {
            e.install(&mut self.graph);
        }
        self.sync_clocks();
        self.sync_copied();
        r
    }

    /// Places request `name` (an AFE request name such as `ratemap`) with the AFE
    /// parameters `params` (absent names take their defaults). Processors whose whole
    /// chain has equal parameters are shared with earlier requests.
    ///
    /// ```
    /// use afe_graph::Manager;
    /// use serde_json::json;
    /// let mut mgr = Manager::new(44100.0, 2)?;
    /// let params = [("fb_nChannels".to_string(), json!(16))].into_iter().collect();
    /// mgr.add_request("ratemap", &params)?;
    /// mgr.add_request("ild", &params)?; // shares time, filterbank and IHC with ratemap
    /// assert_eq!(mgr.processor_count(), 1 + 2 + 2 + 2 + 1);
    /// assert!(mgr.add_request("ratemap", &[("rm_wSizeSecs".to_string(), json!(1))].into_iter().collect()).is_err());
    /// # Ok::<(), afe_core::Error>(())
    /// ```
    pub fn add_request(&mut self, name: &str, params: &ParamMap) -> Result<RequestHandle> {
        self.registry.check_parameter_names(params.keys())?;
        self.edit(|m| m.add_request_now(name, params))
            .map_err(|e| afe_core::params::unless_set(e, params))
    }

    fn add_request_now(&mut self, name: &str, params: &ParamMap) -> Result<RequestHandle> {
        let chain = chain_of(&self.registry, name)?;
        let rollback = self.graph.nodes.len();
        let placed = self
            .graph
            .resolve(&self.registry, self.ears, &chain, params, name)
            .and_then(|outputs| self.graph.check_work(name, params).map(|()| outputs));
        match placed {
            Ok(outputs) => {
                self.requests.push(Some(Request {
                    outputs,
                    params: params.clone(),
                }));
                Ok(RequestHandle(self.requests.len() - 1))
            }
            Err(e) => {
                self.graph.nodes.truncate(rollback);
                for node in &mut self.graph.nodes {
                    node.feedback_from = node.feedback_from.filter(|f| f.node < rollback);
                }
                Err(e)
            }
        }
    }

    /// Removes a request. Its processors go when no other request uses them; the others
    /// keep their state.
    pub fn remove_request(&mut self, handle: RequestHandle) -> Result<()> {
        match self.requests.get(handle.0) {
            Some(Some(_)) => {}
            _ => return Err(Error::UnknownHandle(handle.0)),
        }
        self.edit(|m| {
            m.requests[handle.0] = None;
            m.prune();
            Ok(())
        })
    }

    /// Drops the nodes that no remaining request needs, renumbering the others.
    fn prune(&mut self) {
        let needed: Vec<OutputRef> = self
            .requests
            .iter()
            .flatten()
            .flat_map(|r| r.outputs.iter().copied())
            .collect();
        let new_index = self.graph.prune(needed.into_iter());
        let mut clocks = vec![Vec::new(); self.graph.nodes.len()];
        for (old, c) in std::mem::take(&mut self.clocks).into_iter().enumerate() {
            if let Some(slot) = new_index.get(old).and_then(|&i| clocks.get_mut(i)) {
                *slot = c;
            }
        }
        self.clocks = clocks;
        for r in self.requests.iter_mut().flatten() {
            for o in &mut r.outputs {
                o.node = new_index[o.node];
            }
        }
    }

    /// Changes parameter `name` of the processors of request `handle` that declare it,
    /// between chunks, with the AFE's semantics: those processors are rebuilt and reset,
    /// and so is everything computed from them (in every request sharing them). The
    /// parameters that fix the channel grid cannot be changed.
    pub fn modify_parameter(
        &mut self,
        handle: RequestHandle,
        name: &str,
        value: Value,
    ) -> Result<()> {
        let single: ParamMap = [(name.to_string(), value)].into_iter().collect();
        self.registry.check_parameter_names(single.keys())?;
        if self
            .registry
            .requests()
            .iter()
            .any(|r| r.fixed.contains(&name))
        {
            return Err(Error::invalid(
                name,
                &single[name],
                "this parameter cannot be changed at run time (as in the AFE); place a new \
                 request instead",
            ));
        }
        let Some(Some(req)) = self.requests.get(handle.0) else {
            return Err(Error::UnknownHandle(handle.0));
        };
        let mut params = req.params.clone();
        params.extend(single);
        let chain = self.graph.ancestors(req.outputs.iter().copied());
        let used = chain.iter().any(|&i| {
            self.graph.nodes[i]
                .def
                .is_some_and(|d| d.params.iter().any(|p| p.name == name))
        });
        if !used {
            return Err(Error::invalid(
                name,
                &params[name],
                format!("no processor of request {} uses this parameter", handle.0),
            ));
        }
        self.edit(|m| {
            for n in m.graph.modify(&chain, name, &params[name])? {
                m.restart_clocks(n);
            }
            if let Some(Some(req)) = m.requests.get_mut(handle.0) {
                req.params.insert(name.to_string(), params[name].clone());
            }
            Ok(())
        })
        .map_err(|e| afe_core::params::unless_set(e, &params))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn requests_share_their_common_chain() {
        // input ─ time ─┬─ filterbank L ─ ihc L ─┬─ ratemap L
        //               └─ filterbank R ─ ihc R ─┼─ ratemap R
        //                                        ├─ ild
        //                                        └─ crosscorrelation ─┬─ itd
        //                                                             └─ ic
        let mut m = Manager::new(16000.0, 2).expect("valid");
        m.add_request("ratemap", &ParamMap::new()).expect("ok");
        assert_eq!(m.processor_count(), 1 + 2 + 2 + 2);
        m.add_request("ild", &ParamMap::new()).expect("ok");
        m.add_request("itd", &ParamMap::new()).expect("ok");
        m.add_request("ic", &ParamMap::new()).expect("ok");
        assert_eq!(m.processor_count(), 7 + 1 + 1 + 1 + 1);
        // differing only in ild_* keeps the filterbank shared
        m.add_request("ild", &params(&[("ild_wSizeSec", json!(0.04))]))
            .expect("ok");
        assert_eq!(m.processor_count(), 12);
        // a different filterbank duplicates everything above time
        let h = m
            .add_request("ratemap", &params(&[("fb_nChannels", json!(16))]))
            .expect("ok");
        assert_eq!(m.processor_count(), 12 + 6);
        let keys = output_keys(&m, h);
        assert_eq!(keys, vec!["ratemap_2_left", "ratemap_2_right"]);
    }

    #[test]
    fn binaural_request_on_mono_input_is_rejected_and_leaves_nothing() {
        let mut m = Manager::new(16000.0, 1).expect("valid");
        let e = m.add_request("itd", &ParamMap::new()).expect_err("mono");
        assert!(matches!(e, Error::BinauralOnMono(ref r) if r == "itd"));
        assert_eq!(m.processor_count(), 0);
        let h = m.add_request("ratemap", &ParamMap::new()).expect("mono ok");
        assert_eq!(m.request_signals(h).expect("ok")[0].key(), "ratemap_mono");
    }

    /// A binaural request on `time` (duet) reads both outputs of the one pre-processor
    /// (flag 2, one output per ear); on a mono input it is refused.
    #[test]
    fn a_binaural_request_on_time_reads_both_preproc_outputs() {
        let mut m = Manager::new(16000.0, 2).expect("valid");
        let h = m.add_request("duet", &ParamMap::new()).expect("ok");
        let duet = m.request_signals(h).expect("ok")[0].source.node;
        let parents: Vec<(&str, usize)> = m.graph.nodes[duet]
            .parents
            .iter()
            .map(|p| (m.graph.nodes[p.node].name, p.output))
            .collect();
        assert_eq!(parents, [("time", 0), ("time", 1)]);
        assert_eq!(m.request_signals(h).expect("ok")[0].key(), "duet_mono");
        let mut mono = Manager::new(16000.0, 1).expect("valid");
        let e = mono
            .add_request("duet", &ParamMap::new())
            .expect_err("mono");
        assert!(matches!(e, Error::BinauralOnMono(ref r) if r == "duet"));
    }

    /// issue 46: a value the request set is never called "(the default)", even when it
    /// equals the default (`fb_highFreqHz = 8000` at 11025 Hz); left unset, it is.
    #[test]
    fn a_value_set_is_not_called_the_default() {
        let mut m = Manager::new(11025.0, 2).expect("valid");
        let e = m
            .add_request("ratemap", &params(&[("fb_highFreqHz", json!(8000))]))
            .expect_err("above Nyquist")
            .to_string();
        assert!(
            e.starts_with("invalid value 8000.0 for parameter 'fb_highFreqHz': 8000 puts "),
            "{e}"
        );
        assert!(!e.contains("the default"), "{e}");
        let e = m
            .add_request("ratemap", &ParamMap::new())
            .expect_err("above Nyquist")
            .to_string();
        assert!(e.contains(": 8000 (the default) puts "), "{e}");
        // modify_parameter too: ams_highFreqHz set to its default at 8 kHz
        let mut m = Manager::new(8000.0, 1).expect("valid");
        let fits = params(&[
            ("fb_highFreqHz", json!(3000)),
            ("ams_highFreqHz", json!(256)),
        ]);
        let h = m.add_request("amsFeatures", &fits).expect("fits");
        let e = m
            .modify_parameter(h, "ams_highFreqHz", json!(1024))
            .expect_err("above Nyquist")
            .to_string();
        assert!(
            e.contains("with ams_highFreqHz = 1024, the modulation band"),
            "{e}"
        );
    }

    #[test]
    fn unknown_names_and_bad_input_are_clear_errors() {
        let mut m = Manager::new(16000.0, 2).expect("valid");
        let e = m
            .add_request("ratemap", &params(&[("rm_wSizeSeconds", json!(0.1))]))
            .expect_err("unknown");
        assert!(e.to_string().contains("did you mean 'rm_wSizeSec'"), "{e}");
        let e = m
            .add_request("ratemapp", &ParamMap::new())
            .expect_err("unknown");
        assert!(e.to_string().contains("unknown request 'ratemapp'"), "{e}");
        let e = m
            .add_request("ratemap", &params(&[("fb_nChannels", json!("many"))]))
            .expect_err("ill-typed");
        assert!(e.to_string().contains("fb_nChannels"), "{e}");
        m.add_request("ratemap", &ParamMap::new()).expect("ok");
        let x = [0.0, f64::NAN];
        let e = m.process_chunk(&[&x, &x]).expect_err("NaN");
        assert!(
            e.to_string()
                .contains("sample 1 of the left channel is NaN"),
            "{e}"
        );
        // later in the stream, the position counts from the start of the stream
        m.process_chunk(&[&[0.0; 3], &[0.0; 3]]).expect("finite");
        let e = m.process_chunk(&[&x, &x]).expect_err("NaN");
        assert!(
            e.to_string().contains("sample 4 of the left channel"),
            "{e}"
        );
        // issue 13, item 4: finite but overflowing input is refused, not turned into NaN
        let huge = [0.0, 1e200];
        let e = m.process_chunk(&[&huge, &huge]).expect_err("overflow");
        let msg = e.to_string();
        assert!(
            msg.contains("sample 4 of the left channel is 1e200"),
            "{msg}"
        );
        assert!(msg.contains("scale the input"), "{msg}");
        m.process_chunk(&[&[MAX_AMPLITUDE; 2], &[-MAX_AMPLITUDE; 2]])
            .expect("the largest accepted amplitude");
        // issue 57, item 5: a level-scaling gain of 1e20 (accepted) lowers the amplitude
        // accepted by as much (float32 noise at 1e18 through it gave an Inf STFT)
        let mut loud = Manager::new(16000.0, 2).expect("manager");
        let params: ParamMap = serde_json::from_value(serde_json::json!({
            "pp_bLevelScaling": true, "pp_refSPLdB": -300.0
        }))
        .expect("params");
        loud.add_request("stft", &params).expect("stft");
        let e = loud
            .process_chunk(&[&[1e-4; 4], &[0.0; 4]])
            .expect_err("1e16 after the gain");
        let msg = e.to_string();
        assert!(msg.contains("'time' raises it by up to 1e20"), "{msg}");
        assert!(msg.contains("pp_refSPLdB"), "{msg}");
        loud.process_chunk(&[&[1e-5; 4], &[-1e-5; 4]])
            .expect("1e15 after the gain");
        let e = m.process_chunk(&[&x]).expect_err("mono chunk");
        assert!(e.to_string().contains("got 1 channel(s)"), "{e}");
        let e = m.process_signal(&[&[], &[]]).expect_err("empty");
        assert!(e.to_string().contains("empty"), "{e}");
        assert!(Manager::new(f64::NAN, 2).is_err());
        assert!(Manager::new(16000.0, 3).is_err());
    }

    /// Every parameter of every registered request turns an ill-typed value into an error
    /// that names the parameter and says what it accepts, and places nothing.
    #[test]
    fn every_parameter_rejects_an_ill_typed_value_by_name() {
        use afe_core::ParamKind;
        for r in afe_processors::requests() {
            for spec in r.params {
                let bad = match spec.kind {
                    ParamKind::Choice(_) | ParamKind::Choices(_) => json!("no-such-choice"),
                    ParamKind::Flag => json!("maybe"),
                    ParamKind::Text => json!(5),
                    _ => json!("many"),
                };
                let mut m = Manager::new(16000.0, 2).expect("valid");
                let e = m
                    .add_request(r.name, &params(&[(spec.name, bad)]))
                    .expect_err("ill-typed")
                    .to_string();
                assert!(e.contains(spec.name), "{}/{}: {e}", r.name, spec.name);
                assert!(
                    e.contains("expected") || e.contains("one of"),
                    "{}/{}: {e}",
                    r.name,
                    spec.name
                );
                assert_eq!(m.processor_count(), 0, "{}/{}", r.name, spec.name);
            }
        }
    }
}
