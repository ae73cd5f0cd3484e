//! The audio path allocates nothing: after `Manager::prepare` with the chunk size in use,
//! the scheduler's worker threads make no allocation at all, from the first chunk on (a
//! counting global allocator checks it on the real {ratemap, ild, itd, ic} graph, with
//! the cross-correlation split over the workers, and `amsFeatures`, whose hop sums are
//! swapped at every hop and cleared by the reset that ends `prepare`).

#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use afe_core::ParamMap;
use afe_graph::Manager;
use serde_json::json;

struct Counting;

static WORKER_ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts.

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if afe_graph::is_worker_thread() {
            WORKER_ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if afe_graph::is_worker_thread() {
            WORKER_ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if afe_graph::is_worker_thread() {
            WORKER_ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

#[test]
fn workers_do_not_allocate_after_prepare() {
    let fs = 44100.0;
    let x: Vec<f64> = (0..44100).map(|t| (0.05 * t as f64).sin() * 0.3).collect();
    let y: Vec<f64> = x.iter().map(|v| 0.5 * v).collect();
    for threads in [1, 2, 4] {
        for prepared in [false, true] {
            let mut mgr = Manager::with_threads(fs, 2, threads).expect("manager");
            let big: ParamMap = [("fb_nChannels".to_string(), json!(40))]
                .into_iter()
                .collect();
            for p in [ParamMap::new(), big] {
                for r in ["ratemap", "ild", "itd", "ic", "amsFeatures"] {
                    mgr.add_request(r, &p).expect("request");
                }
            }
            if prepared {
                mgr.prepare(441).expect("prepare");
            }
            let start = WORKER_ALLOCATIONS.load(Ordering::SeqCst);
            for (l, r) in x.chunks(441).zip(y.chunks(441)).take(90) {
                mgr.submit_chunk(&[l, r]).expect("submit");
                if mgr.in_flight() >= mgr.pipeline_depth() {
                    mgr.collect_chunk().expect("collect");
                }
            }
            while mgr.in_flight() > 0 {
                mgr.collect_chunk().expect("collect");
            }
            let allocations = WORKER_ALLOCATIONS.load(Ordering::SeqCst) - start;
            if prepared {
                assert_eq!(allocations, 0, "{threads} workers allocated after prepare");
            } else {
                // the counter sees the workers: unprepared buffers grow in the first chunks
                assert!(allocations > 0, "{threads} workers: no allocation seen");
            }
        }
    }
}
