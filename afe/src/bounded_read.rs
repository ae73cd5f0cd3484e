//! Reading a small file whole, up to a bound: a parameter file, a manifest, a store's
//! metadata. A wrong path (`/dev/zero`, a WAV file, a device) fails at once, naming the
//! bound, instead of filling the memory.

use std::io::Read;
use std::path::Path;

/// The text of `path`, if it holds at most `max_bytes` bytes of UTF-8. Beyond the bound,
/// an error of kind `InvalidData` saying `larger than N KiB`, after reading at most
/// `max_bytes + 1` bytes. A FIFO or device is opened and read inside an
/// [`afe_core::interrupt::InputWait`], so that the CLI's first SIGINT or SIGTERM ends a
/// wait for a writer that never comes (`--params` naming a FIFO).
///
/// ```
/// let e = afe::bounded_read::read_text(std::path::Path::new("/dev/zero"), 1024).unwrap_err();
/// assert_eq!(e.to_string(), "larger than 1 KiB");
/// ```
pub fn read_text(path: &Path, max_bytes: u64) -> std::io::Result<String> {
    let mut bytes = Vec::new();
    let blocking = std::fs::metadata(path).is_ok_and(|m| !m.is_file());
    let _wait = blocking.then(afe_core::interrupt::InputWait::start);
    std::fs::File::open(path)?
        .take(max_bytes + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max_bytes {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("larger than {} KiB", max_bytes >> 10),
        ));
    }
    String::from_utf8(bytes)
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidData, "not UTF-8 text"))
}
