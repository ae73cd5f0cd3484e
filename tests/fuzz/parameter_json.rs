//! Target 2: parameter JSON into the parameter parser and the request resolver.

use afe::Manager;
use serde_json::json;

use super::draws::{junk_name, random_fs, random_params, random_signal};
use super::{check_error, check_outputs, count, fuzz, note, CASE_LIMIT};

#[test]
fn parameter_json() {
    let names: Vec<&str> = afe::requests().iter().map(|r| r.name).collect();
    fuzz("parameter_json", |rng, _| {
        let fs = random_fs(rng);
        let ears = if rng.one_in(20) {
            *rng.pick(&[0, 3])
        } else {
            1 + rng.below(2)
        };
        let threads = if rng.one_in(8) { 2 } else { 0 };
        let mut mgr = match Manager::with_threads(fs, ears, threads) {
            Ok(m) => m,
            Err(e) => return check_error(&e),
        };
        mgr.set_stall_timeout(CASE_LIMIT);
        mgr.set_keep_all(true);
        let mut accepted = false;
        for _ in 0..1 + rng.below(3) {
            let name = if rng.one_in(12) {
                {
                    let real = *rng.pick(&names);
                    junk_name(rng, real)
                }
            } else {
                rng.pick(&names).to_string()
            };
            let entries = rng.below(7);
            let params = random_params(rng, &name, entries);
            // the parser alone, for every processor (the resolver stops at the first error)
            for def in afe::requests() {
                if let Err(e) = (def.configure)(&params) {
                    check_error(&e)?;
                }
            }
            note(|| {
                format!(
                    "add_request({name:?}, {}) at {fs} Hz, {ears} ear(s)",
                    json!(params)
                )
            });
            match mgr.add_request(&name, &params) {
                Ok(_) => {
                    count("request accepted");
                    accepted = true;
                }
                Err(e) => {
                    count("request refused");
                    check_error(&e)?;
                }
            }
        }
        if accepted {
            let len = rng.below(2000);
            let x = random_signal(rng, len);
            let chunk: Vec<&[f64]> = vec![x.as_slice(); ears];
            // a chunk, or a whole signal (where a graph depends on chunk boundaries, its
            // own path through the graph)
            let whole = rng.one_in(3);
            note(|| {
                format!(
                    "{} of {len} samples",
                    if whole {
                        "process_signal"
                    } else {
                        "process_chunk"
                    }
                )
            });
            let result = if whole {
                mgr.process_signal(&chunk)
            } else {
                mgr.process_chunk(&chunk)
            };
            match result {
                Ok(()) if !whole => {
                    count("chunk processed");
                    check_outputs(&mgr, len)?;
                }
                Ok(()) => count("whole signal processed"),
                Err(e) => {
                    count("processing refused");
                    check_error(&e)?;
                }
            }
        }
        Ok(())
    });
}
