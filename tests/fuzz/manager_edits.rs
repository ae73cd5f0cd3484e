//! Target 3: random chunkings and run-time edits, sequential and concurrent in lockstep.

use std::collections::VecDeque;

use afe::{Manager, ParamMap, RequestHandle};
use serde_json::{json, Value};

use super::draws::{random_params, random_signal};
use super::{check_error, check_outputs, count, fuzz, note, CASE_LIMIT, MAX_FRAMES};

/// The requested outputs shown after a chunk: key and values.
type Snapshot = Vec<(String, usize, Vec<f64>)>;

fn snapshot(mgr: &Manager) -> Snapshot {
    mgr.signals(false)
        .iter()
        .map(|s| (s.key(), s.new.width(), s.new.as_slice().to_vec()))
        .collect()
}

/// Bit-for-bit equality of two snapshots (NaN equal to itself).
fn same(a: &Snapshot, b: &Snapshot) -> Result<(), String> {
    if a.len() != b.len() {
        return Err(format!(
            "{} signals sequentially, {} concurrently",
            a.len(),
            b.len()
        ));
    }
    for ((ka, wa, da), (kb, wb, db)) in a.iter().zip(b) {
        if ka != kb || wa != wb || da.len() != db.len() {
            return Err(format!(
                "{ka} ({wa} × {}) sequentially, {kb} ({wb} × {}) concurrently",
                da.len(),
                db.len()
            ));
        }
        if let Some(i) = da
            .iter()
            .zip(db)
            .position(|(x, y)| x.to_bits() != y.to_bits())
        {
            return Err(format!(
                "{ka}[{i}]: {} sequentially, {} concurrently",
                da[i], db[i]
            ));
        }
    }
    Ok(())
}

/// The same operation's outcome on both executors.
fn agree<T>(what: &str, a: &afe::Result<T>, b: &afe::Result<T>) -> Result<(), String> {
    count(&format!(
        "{what}: {}",
        if a.is_ok() { "done" } else { "refused" }
    ));
    match (a, b) {
        (Ok(_), Ok(_)) => Ok(()),
        (Err(x), Err(y)) if x == y => check_error(x),
        (Err(e), Ok(_)) => Err(format!(
            "{what}: sequential error '{e}', concurrent success"
        )),
        (Ok(_), Err(e)) => Err(format!(
            "{what}: sequential success, concurrent error '{e}'"
        )),
        (Err(x), Err(y)) => Err(format!(
            "{what}: sequential error '{x}', concurrent error '{y}'"
        )),
    }
}

/// `params` with at most 32 channels (the edit target is about edits, not sizes: two
/// managers with 1024 channels of autocorrelation hold hundreds of MB).
fn small(mut params: ParamMap) -> ParamMap {
    if let Some(v) = params.get_mut("fb_nChannels") {
        if v.as_f64().is_some_and(|n| n > 32.0) {
            *v = json!(32);
        }
    }
    if let Some(Value::Array(cf)) = params.get_mut("fb_cfHz") {
        cf.truncate(32);
    }
    params
}

/// The concurrent manager's outputs waiting to be compared: the sequential snapshots of
/// the chunks it has in flight, oldest first.
struct Lockstep {
    seq: Manager,
    con: Manager,
    queue: VecDeque<Snapshot>,
}

impl Lockstep {
    /// Collects every chunk the concurrent manager has in flight and compares each.
    fn drain(&mut self) -> Result<(), String> {
        while self.con.in_flight() > 0 {
            let r = self.con.collect_chunk();
            if let Err(e) = &r {
                check_error(e)?;
                return Err(format!("collecting a chunk failed: {e}"));
            }
            let want = self
                .queue
                .pop_front()
                .ok_or("a chunk in flight without its sequential twin")?;
            same(&want, &snapshot(&self.con))?;
        }
        Ok(())
    }

    /// A chunk into both: processed at once sequentially, pipelined concurrently.
    fn chunk(&mut self, x: &[f64]) -> Result<(), String> {
        let ears = self.seq.ears();
        let chunk: Vec<&[f64]> = vec![x; ears];
        let a = self.seq.process_chunk(&chunk);
        if self.con.in_flight() >= self.con.pipeline_depth() {
            let r = self.con.collect_chunk();
            if let Err(e) = &r {
                check_error(e)?;
                return Err(format!("collecting a chunk failed: {e}"));
            }
            let want = self
                .queue
                .pop_front()
                .ok_or("a chunk in flight without its sequential twin")?;
            same(&want, &snapshot(&self.con))?;
        }
        let b = self.con.submit_chunk(&chunk);
        agree("chunk", &a, &b)?;
        if a.is_ok() {
            check_outputs(&self.seq, x.len())?;
            self.queue.push_back(snapshot(&self.seq));
        }
        Ok(())
    }
}

#[test]
fn manager_edits() {
    fuzz("manager_edits", |rng, _| {
        let fs = *rng.pick(&[8000.0, 16000.0, 22050.0, 44100.0, 48000.0]);
        let ears = 1 + rng.below(2);
        let mut seq = Manager::new(fs, ears).map_err(|e| e.to_string())?;
        let mut con = Manager::with_threads(fs, ears, 2).map_err(|e| e.to_string())?;
        con.set_stall_timeout(CASE_LIMIT);
        // every signal, intermediate ones too, is compared between the executors
        seq.set_keep_all(true);
        con.set_keep_all(true);
        note(|| format!("{fs} Hz, {ears} ear(s)"));
        let mut m = Lockstep {
            seq,
            con,
            queue: VecDeque::new(),
        };
        let mut handles: Vec<(usize, &str)> = Vec::new();
        let mut fed = 0;
        for _ in 0..4 + rng.below(30) {
            if fed >= 4 * MAX_FRAMES {
                break;
            }
            match rng.below(12) {
                0..=2 => {
                    let name = rng.pick(afe::requests()).name;
                    let entries = rng.below(3);
                    let mut params = small(random_params(rng, name, entries));
                    if !params.contains_key("fb_nChannels") && !rng.one_in(4) {
                        params.insert("fb_nChannels".into(), json!(1 + rng.below(12)));
                    }
                    m.drain()?;
                    note(|| format!("add_request({name:?}, {})", json!(params)));
                    let a = m.seq.add_request(name, &params);
                    let b = m.con.add_request(name, &params);
                    agree("add_request", &a, &b)?;
                    if let (Ok(x), Ok(y)) = (&a, &b) {
                        if x != y {
                            return Err(format!("handles {x:?} and {y:?} for the same request"));
                        }
                        handles.push((x.index(), name));
                    }
                }
                3 => {
                    let h = RequestHandle::from_index(rng.below(handles.len() + 2));
                    note(|| format!("remove_request({})", h.index()));
                    m.drain()?;
                    agree(
                        "remove_request",
                        &m.seq.remove_request(h),
                        &m.con.remove_request(h),
                    )?;
                }
                4 | 5 => {
                    let (h, name) = match handles.is_empty() {
                        true => (rng.below(3), "ratemap"),
                        false => *rng.pick(&handles),
                    };
                    let params = small(random_params(rng, name, 1));
                    let Some((key, value)) = params.into_iter().next() else {
                        continue;
                    };
                    m.drain()?;
                    let h = RequestHandle::from_index(h);
                    note(|| format!("modify_parameter({}, {key:?}, {value})", h.index()));
                    let a = m.seq.modify_parameter(h, &key, value.clone());
                    let b = m.con.modify_parameter(h, &key, value);
                    agree("modify_parameter", &a, &b)?;
                }
                6 => {
                    m.drain()?;
                    note(|| "reset".into());
                    agree("reset", &m.seq.reset(), &m.con.reset())?;
                }
                7 => {
                    m.drain()?;
                    let len = rng.below(3000);
                    let x = random_signal(rng, len);
                    let chunk: Vec<&[f64]> = vec![x.as_slice(); ears];
                    note(|| format!("process_signal({len} samples)"));
                    let a = m.seq.process_signal(&chunk);
                    let b = m.con.process_signal(&chunk);
                    agree("process_signal", &a, &b)?;
                    if a.is_ok() {
                        same(&snapshot(&m.seq), &snapshot(&m.con))?;
                    }
                    fed += x.len();
                }
                _ => {
                    let len = match rng.below(6) {
                        0 => rng.below(3),
                        1 => 2000 + rng.below(1000),
                        _ => rng.below(700),
                    };
                    let mut x = random_signal(rng, len);
                    if len > 0 && rng.one_in(40) {
                        x[rng.below(len)] = *rng.pick(&[f64::NAN, f64::INFINITY, 1e200]);
                    }
                    note(|| format!("chunk of {len} samples"));
                    m.chunk(&x)?;
                    fed += len;
                }
            }
        }
        m.drain()
    });
}
