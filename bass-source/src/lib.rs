//! The BASS-compatible audio source of `afe`: a sliding-window port with a 64-bit frame
//! index and the BASC block reader. Not implemented yet (its own issue); the crate exists
//! so that the workspace has its final shape and dependency direction.
