//! Resident memory of this process, read without allocating (a live stream samples it
//! once per second of audio to show that its memory stays flat).

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::sync::Arc;

/// Reads `VmRSS` from `/proc/self/status` into a fixed buffer.
#[derive(Debug, Clone)]
pub struct RssProbe {
    file: Option<Arc<File>>,
    buf: Box<[u8; 4096]>,
}

impl Default for RssProbe {
    fn default() -> Self {
        RssProbe {
            file: File::open("/proc/self/status").ok().map(Arc::new),
            buf: Box::new([0; 4096]),
        }
    }
}

impl RssProbe {
    /// Resident memory in KiB (`None` where `/proc` is not there).
    pub fn read_kib(&mut self) -> Option<u64> {
        let n = self.file.as_ref()?.read_at(&mut self.buf[..], 0).ok()?;
        parse_vm_rss(&self.buf[..n])
    }
}

/// The number on the `VmRSS:` line of a `/proc/<pid>/status` text, in KiB.
fn parse_vm_rss(text: &[u8]) -> Option<u64> {
    let key = b"VmRSS:";
    let at = text.windows(key.len()).position(|w| w == key)? + key.len();
    let digits = text[at..]
        .iter()
        .skip_while(|b| b.is_ascii_whitespace())
        .take_while(|b| b.is_ascii_digit());
    let mut value: u64 = 0;
    let mut any = false;
    for d in digits {
        value = value.checked_mul(10)?.checked_add(u64::from(d - b'0'))?;
        any = true;
    }
    any.then_some(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_vm_rss_line() {
        let text = b"Name:\tafe\nVmPeak:\t  9999 kB\nVmRSS:\t   12345 kB\nRssAnon:\t 1 kB\n";
        assert_eq!(parse_vm_rss(text), Some(12345));
        assert_eq!(parse_vm_rss(b"VmRSS:\t kB\n"), None);
        assert_eq!(parse_vm_rss(b"nothing"), None);
        // this process has some resident memory
        assert!(RssProbe::default().read_kib().is_some_and(|k| k > 100));
    }
}
