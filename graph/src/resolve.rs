//! Request resolution and graph editing (spec 00-overview §3–§5, §10): a request becomes a
//! chain of processors, each shared with earlier requests whose whole chain has equal
//! parameters; removing a request prunes what nobody uses; modifying a parameter rebuilds
//! the processors that declare it and everything computed from them. Execution lives in
//! [`crate::manager`] and the executors; nothing here runs a processor.

use std::sync::Arc;

use afe_core::{Block, Configured, Error, ParamMap, Result, SignalInfo};
use afe_processors::{Ears, Registry, RequestDef};

use crate::graph::{Channel, Graph, Node, OutputRef, MAX_INPUTS};

/// The request definitions from `name` down to the input, `name` first.
pub(crate) fn chain_of(registry: &Registry, name: &str) -> Result<Vec<&'static RequestDef>> {
    let mut chain: Vec<&'static RequestDef> = vec![registry.find(name)?];
    while chain[chain.len() - 1].dependency != "input" {
        chain.push(registry.find(chain[chain.len() - 1].dependency)?);
    }
    Ok(chain)
}

impl Graph {
    /// Places the processors of request `request` (its chain, `request` first) with the
    /// request parameters `params`, sharing every node whose own parameters and parents
    /// are equal (extra inputs found in `registry`); returns the request's outputs. On
    /// error, nodes added so far stay: the caller truncates to the length it had.
    pub(crate) fn resolve(
        &mut self,
        registry: &Registry,
        ears: usize,
        chain: &[&'static RequestDef],
        params: &ParamMap,
        request: &str,
    ) -> Result<Vec<OutputRef>> {
        let mut level: Vec<OutputRef> = (0..ears)
            .map(|output| OutputRef { node: 0, output })
            .collect();
        for def in chain.iter().rev() {
            let config: Arc<dyn Configured> = (def.configure)(params)?.into();
            let own = config.canonical();
            let mut extras: Vec<Vec<OutputRef>> = Vec::new();
            for extra in config.extra_inputs() {
                extras.push(self.resolve(
                    registry,
                    ears,
                    &chain_of(registry, extra)?,
                    params,
                    request,
                )?);
            }
            let groups: Vec<Vec<OutputRef>> = match def.ears {
                Ears::All => vec![level.clone()],
                Ears::PerEar => level
                    .iter()
                    .enumerate()
                    .map(|(ear, r)| {
                        let mut g = vec![*r];
                        g.extend(extras.iter().map(|e| e[ear.min(e.len() - 1)]));
                        g
                    })
                    .collect(),
                Ears::Binaural => {
                    if level.len() == 1 && !self.is_binaural(level[0]) {
                        return Err(Error::BinauralOnMono(request.to_string()));
                    }
                    let mut g = level.clone();
                    g.extend(extras.iter().flatten());
                    vec![g]
                }
            };
            let instance = self.instance_for(def.name, own, &groups);
            let mut next = Vec::new();
            for parents in groups {
                let node = match self.find_node(def.name, own, &parents) {
                    Some(n) => n,
                    None => self.add_node(def, params, &config, parents, instance)?,
                };
                if let Some(target) = def.feeds_back_to {
                    self.connect_feedback(node, target)?;
                }
                next.extend(
                    self.nodes[node]
                        .infos
                        .iter()
                        .enumerate()
                        .filter(|(_, info)| !info.feedback)
                        .map(|(output, _)| OutputRef { node, output }),
                );
            }
            level = next;
        }
        Ok(level)
    }

    /// Makes the nearest node named `target` below `source` (following first parents,
    /// so on the same ear) take `source`'s feedback output. A node takes the feedback of
    /// one source only: a second request that would feed the same filterbank from other
    /// parameters is refused rather than letting two MOCs overwrite each other.
    fn connect_feedback(&mut self, source: usize, target: &str) -> Result<()> {
        let Some(output) = self.nodes[source].infos.iter().position(|i| i.feedback) else {
            return Ok(());
        };
        let from = OutputRef {
            node: source,
            output,
        };
        let mut n = source;
        while self.nodes[n].name != target {
            match self.nodes[n].parents.first() {
                Some(p) => n = p.node,
                None => return Ok(()),
            }
        }
        match self.nodes[n].feedback_from {
            Some(f) if f != from => Err(Error::InvalidInput(format!(
                "the {target} below this {} already takes the feedback of a {} with other \
                 parameters; use one set of {} parameters per {target}",
                self.nodes[source].name, self.nodes[f.node].name, self.nodes[source].name
            ))),
            _ => {
                self.nodes[n].feedback_from = Some(from);
                Ok(())
            }
        }
    }

    /// Whether `r` is the output of a binaural processor (a cue computed from both ears).
    fn is_binaural(&self, r: OutputRef) -> bool {
        self.nodes[r.node]
            .def
            .is_some_and(|d| d.ears == Ears::Binaural)
    }

    fn find_node(&self, name: &str, params: &ParamMap, parents: &[OutputRef]) -> Option<usize> {
        self.nodes
            .iter()
            .position(|n| n.name == name && &n.params == params && n.parents == parents)
    }

    /// The instance number for a new node of `name`: the one of an existing node with the
    /// same parameters (the other ear of the same request), or one more than the largest.
    fn instance_for(&self, name: &str, params: &ParamMap, groups: &[Vec<OutputRef>]) -> usize {
        if let Some(n) = groups
            .iter()
            .find_map(|parents| self.find_node(name, params, parents))
        {
            return self.nodes[n].instance;
        }
        1 + self
            .nodes
            .iter()
            .filter(|n| n.name == name)
            .map(|n| n.instance)
            .max()
            .unwrap_or(0)
    }

    /// Builds a node from `config`, the request's `params` parsed for `def`.
    fn add_node(
        &mut self,
        def: &'static RequestDef,
        params: &ParamMap,
        config: &Arc<dyn Configured>,
        parents: Vec<OutputRef>,
        instance: usize,
    ) -> Result<usize> {
        if parents.len() > MAX_INPUTS {
            return Err(Error::InvalidInput(format!(
                "{} would read {} inputs; a node reads at most {MAX_INPUTS}",
                def.name,
                parents.len()
            )));
        }
        let inputs: Vec<SignalInfo> = parents
            .iter()
            .map(|p| self.nodes[p.node].infos[p.output].clone())
            .collect();
        let mut built = config.build(&inputs, &self.context)?;
        let channels = match def.ears {
            Ears::All => parents
                .iter()
                .map(|p| self.nodes[p.node].channels[p.output])
                .collect(),
            Ears::PerEar => {
                vec![self.nodes[parents[0].node].channels[parents[0].output]; built.outputs.len()]
            }
            Ears::Binaural => vec![Channel::Mono; built.outputs.len()],
        };
        let outputs = built
            .outputs
            .iter()
            .map(|info| Block::new(info.width()))
            .collect();
        self.nodes.push(Node {
            name: def.name,
            def: Some(def),
            config: Some(Arc::clone(config)),
            request_params: params.clone(),
            instance,
            params: config.canonical().clone(),
            parents,
            feedback_from: None,
            absorbs: built.processor.whole_signal().is_some(),
            processor: Some(built.processor),
            outputs,
            infos: built.outputs,
            channels,
            input_gain: built.input_gain,
        });
        Ok(self.nodes.len() - 1)
    }

    /// Drops the nodes that none of `needed` (the outputs of the remaining requests) is
    /// computed from, renumbering the others; returns the new index of each old node
    /// (`usize::MAX` for a dropped one).
    pub(crate) fn prune(&mut self, needed: impl Iterator<Item = OutputRef>) -> Vec<usize> {
        let n = self.nodes.len();
        let mut keep = vec![false; n];
        keep[0] = true;
        for i in self.ancestors(needed) {
            keep[i] = true;
        }
        let mut new_index = vec![usize::MAX; n];
        let mut next = 0;
        for (i, k) in keep.iter().enumerate() {
            if *k {
                new_index[i] = next;
                next += 1;
            }
        }
        let old = std::mem::take(&mut self.nodes);
        self.nodes = old
            .into_iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(mut node, _)| {
                for p in &mut node.parents {
                    p.node = new_index[p.node];
                }
                node.feedback_from = node
                    .feedback_from
                    .filter(|f| new_index[f.node] != usize::MAX)
                    .map(|f| OutputRef {
                        node: new_index[f.node],
                        output: f.output,
                    });
                node
            })
            .collect();
        new_index
    }

    /// Every node a set of outputs is computed from, the outputs' nodes included, in
    /// graph order.
    pub(crate) fn ancestors(&self, outputs: impl Iterator<Item = OutputRef>) -> Vec<usize> {
        let mut seen = vec![false; self.nodes.len()];
        let mut stack: Vec<usize> = outputs.map(|o| o.node).collect();
        while let Some(i) = stack.pop() {
            if !seen[i] {
                seen[i] = true;
                stack.extend(self.nodes[i].parents.iter().map(|p| p.node));
            }
        }
        (0..seen.len()).filter(|i| seen[*i]).collect()
    }

    /// Sets parameter `name` to `value` in the nodes of `chain` that declare it (each
    /// configured again from the request map it was configured from, with the new value)
    /// and rebuilds them and every node computed from them (fresh state; the others keep
    /// their typed parameters). Every replacement is built before any is installed, so a
    /// rejected value changes nothing. Returns the nodes rebuilt.
    pub(crate) fn modify(
        &mut self,
        chain: &[usize],
        name: &str,
        value: &serde_json::Value,
    ) -> Result<Vec<usize>> {
        let n = self.nodes.len();
        let mut dirty = vec![false; n];
        let mut reconfigured: Vec<(usize, ParamMap, Arc<dyn Configured>)> = Vec::new();
        for &i in chain {
            let node = &self.nodes[i];
            if let Some(def) = node.def {
                if def.params.iter().any(|p| p.name == name) {
                    let mut request = node.request_params.clone();
                    request.insert(name.to_string(), value.clone());
                    let config = (def.configure)(&request)?.into();
                    reconfigured.push((i, request, config));
                    dirty[i] = true;
                }
            }
        }
        for i in 1..n {
            if !dirty[i] && self.nodes[i].parents.iter().any(|p| dirty[p.node]) {
                dirty[i] = true;
            }
        }
        let mut infos: Vec<Vec<SignalInfo>> = self.nodes.iter().map(|n| n.infos.clone()).collect();
        let mut built = Vec::new();
        for i in (1..n).filter(|i| dirty[*i]) {
            let node = &self.nodes[i];
            let (request, config) = match reconfigured.iter().find(|r| r.0 == i) {
                Some((_, request, config)) => (Some(request.clone()), Arc::clone(config)),
                None => (
                    None,
                    node.config.clone().ok_or_else(|| {
                        Error::InvalidInput("the input node cannot be rebuilt".into())
                    })?,
                ),
            };
            let inputs: Vec<SignalInfo> = node
                .parents
                .iter()
                .map(|p| infos[p.node][p.output].clone())
                .collect();
            let b = config.build(&inputs, &self.context)?;
            infos[i] = b.outputs.clone();
            built.push((i, b, request, config));
        }
        let rebuilt_nodes = built.iter().map(|b| b.0).collect();
        for (i, b, request, config) in built {
            let node = &mut self.nodes[i];
            node.outputs = b
                .outputs
                .iter()
                .map(|info| Block::new(info.width()))
                .collect();
            node.infos = b.outputs;
            node.input_gain = b.input_gain;
            let mut processor = b.processor;
            node.absorbs = processor.whole_signal().is_some();
            node.processor = Some(processor);
            if let Some(request) = request {
                node.params = config.canonical().clone();
                node.request_params = request;
            }
            node.config = Some(config);
        }
        Ok(rebuilt_nodes)
    }
}
