//! Where the concurrent scheduler prefers to run each node: a home worker per table
//! entry, so that a chain of nodes (one ear's filterbank, hair cell and ratemap) stays on
//! one core and its children read their input from that core's cache. Homes are a
//! preference only: an idle worker takes any ready node, so they never change a result
//! and never leave a core idle while work is queued.

/// No home: the source, which the caller publishes.
pub(crate) const NO_HOME: usize = usize::MAX;

/// The home worker of each table entry. `parents[e]` are entry `e`'s distinct parent
/// entries (entry 0 is the source); `parts` lists each split node's part entries, part
/// `j` going to worker `j`. The other entries, visited in index order (the graph's nodes
/// are in topological order), continue the chain of their parent when they have one
/// parent besides the source and are its first child visited; otherwise they start on
/// the worker with the fewest entries so far.
pub(crate) fn homes(parents: &[Vec<usize>], parts: &[&[usize]], workers: usize) -> Vec<usize> {
    let mut home = vec![NO_HOME; parents.len()];
    let workers = workers.max(1);
    let mut load = vec![0usize; workers];
    for entries in parts {
        for (j, &e) in entries.iter().enumerate() {
            home[e] = j % workers;
            load[j % workers] += 1;
        }
    }
    let mut continued = vec![false; parents.len()];
    for e in 1..parents.len() {
        if home[e] != NO_HOME {
            continue;
        }
        let own: Vec<usize> = parents[e].iter().copied().filter(|&p| p != 0).collect();
        let w = match own[..] {
            [p] if !continued[p] && home[p] != NO_HOME => {
                continued[p] = true;
                home[p]
            }
            _ => (0..workers).min_by_key(|&w| load[w]).unwrap_or(0),
        };
        home[e] = w;
        load[w] += 1;
    }
    home
}

/// Per worker, the bit mask (64 entries per word) of the entries whose home it is.
pub(crate) fn masks(home: &[usize], workers: usize) -> Vec<Box<[u64]>> {
    let words = home.len().div_ceil(64);
    (0..workers)
        .map(|w| {
            let mut m = vec![0u64; words];
            for (e, _) in home.iter().enumerate().filter(|(_, &h)| h == w) {
                m[e / 64] |= 1 << (e % 64);
            }
            m.into()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default binaural chain: source 0; filterbank 1 (left) and 2 (right); hair
    /// cells 3, 4; ratemaps 5, 6; ild 7; cross-correlation 8 joining parts 11, 12; itd 9;
    /// ic 10.
    fn binaural_chain() -> Vec<Vec<usize>> {
        vec![
            vec![],
            vec![0],
            vec![0],
            vec![1],
            vec![2],
            vec![3],
            vec![4],
            vec![5, 6],
            vec![3, 4, 11, 12],
            vec![8],
            vec![8],
            vec![3, 4],
            vec![3, 4],
        ]
    }

    #[test]
    fn each_ear_keeps_its_chain_and_parts_spread_over_the_workers() {
        let home = homes(&binaural_chain(), &[&[11, 12]], 2);
        assert_eq!(home[0], NO_HOME);
        // left ear on one worker, right ear on the other
        assert_eq!([home[1], home[3], home[5]], [0; 3]);
        assert_eq!([home[2], home[4], home[6]], [1; 3]);
        assert_eq!([home[11], home[12]], [0, 1]);
        // the join's first child continues its chain, the second starts on the less
        // loaded worker
        assert_eq!(home[9], home[8]);
        assert_ne!(home[10], home[8]);
        let per_worker: Vec<usize> = (0..2)
            .map(|w| home.iter().filter(|&&h| h == w).count())
            .collect();
        assert_eq!(per_worker, [6, 6]);
    }

    #[test]
    fn one_worker_is_home_to_everything_and_masks_mark_each_entry_once() {
        let chain = binaural_chain();
        let home = homes(&chain, &[], 1);
        assert!(home[1..].iter().all(|&h| h == 0));
        let home = homes(&chain, &[&[11, 12]], 3);
        let masks = masks(&home, 3);
        for e in 1..chain.len() {
            let owners: Vec<usize> = (0..3)
                .filter(|&w| masks[w][e / 64] & (1 << (e % 64)) != 0)
                .collect();
            assert_eq!(owners, [home[e]], "entry {e}");
        }
        assert!(
            masks.iter().all(|m| m[0] & 1 == 0),
            "the source has no home"
        );
    }
}
