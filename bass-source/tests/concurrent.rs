//! One writer at full speed, several readers at different speeds: every frame published is
//! delivered once or counted as lost once, and no delivered frame is torn.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use afe_bass_source::{Port, PortFormat, Reader};

/// Frame `f`'s samples: both channels encode the frame index, so a frame overwritten
/// during a copy (index `f + capacity`) or a mix of two chunks cannot pass for frame `f`.
fn pattern(frame: u64) -> [i32; 2] {
    let f = frame as u32;
    [f as i32, !f.rotate_left(7) as i32]
}

struct Tally {
    delivered: u64,
    lost: u64,
    reads: u64,
    partial: u64,
}

fn read_all(mut reader: Reader<i32>, block: usize, pause: impl Fn(u64)) -> Tally {
    let (mut l, mut r) = (vec![0; block], vec![0; block]);
    let mut t = Tally {
        delivered: 0,
        lost: 0,
        reads: 0,
        partial: 0,
    };
    while !reader.at_end() {
        let got = reader.read(&mut [&mut l, &mut r]).expect("read");
        let first = reader.next_frame() - got.frames as u64;
        for i in 0..got.frames {
            let want = pattern(first + i as u64);
            assert_eq!(
                [l[i], r[i]],
                want,
                "frame {} torn or misplaced",
                first + i as u64
            );
        }
        t.delivered += got.frames as u64;
        t.lost += got.lost;
        t.reads += 1;
        if got.frames > 0 && got.frames < block {
            t.partial += 1;
        }
        pause(t.reads);
    }
    t
}

#[test]
fn delivered_plus_lost_is_published_for_every_reader() {
    let format = PortFormat {
        sample_rate: 44100,
        channels: 2,
        frames_per_chunk: 64,
        chunks_on_port: 8,
    };
    let chunks = 200_000u64;
    let mut writer = Port::<i32>::create(format).expect("port");
    let port = writer.port();
    let started = AtomicBool::new(false);
    let t0 = Instant::now();
    let tallies = std::thread::scope(|s| {
        let readers: Vec<_> = [
            // (block, pause every k reads) — from a reader that keeps up to one that
            // reads blocks longer than the port and sleeps.
            (64usize, 0u64),
            (100, 1),
            (700, 3),
            (1000, 1),
        ]
        .into_iter()
        .map(|(block, every)| {
            let reader = Reader::new(port.clone(), 0);
            let started = &started;
            s.spawn(move || {
                while !started.load(Ordering::Acquire) {
                    std::hint::spin_loop();
                }
                read_all(reader, block, |reads| {
                    if every > 0 && reads % every == 0 {
                        if block >= 700 {
                            std::thread::sleep(Duration::from_micros(50));
                        } else {
                            for _ in 0..200 {
                                std::hint::spin_loop();
                            }
                        }
                    }
                })
            })
        })
        .collect();
        started.store(true, Ordering::Release);
        let (mut l, mut r) = (vec![0; 64], vec![0; 64]);
        for k in 0..chunks {
            for i in 0..64 {
                [l[i], r[i]] = pattern(k * 64 + i as u64);
            }
            writer.publish(&[&l, &r]).expect("publish");
        }
        drop(writer);
        readers
            .into_iter()
            .map(|h| h.join().expect("reader"))
            .collect::<Vec<_>>()
    });
    let published = port.frames_published();
    assert_eq!(published, chunks * 64);
    for (k, t) in tallies.iter().enumerate() {
        assert_eq!(
            t.delivered + t.lost,
            published,
            "reader {k}: {} delivered + {} lost",
            t.delivered,
            t.lost
        );
        assert!(t.delivered > 0, "reader {k} got nothing");
    }
    assert!(
        tallies[3].partial > 0,
        "blocks longer than the port come in several reads"
    );
    assert!(
        tallies.iter().any(|t| t.lost > 0),
        "a reader sleeping while the writer runs at full speed must lose frames"
    );
    assert!(
        t0.elapsed() < Duration::from_secs(20),
        "took {:?}",
        t0.elapsed()
    );
}
