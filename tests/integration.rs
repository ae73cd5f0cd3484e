//! The command line's and the libraries' integration tests, one module per concern, in one
//! test binary: each file as its own binary linked the whole workspace and instantiated
//! its network and store stacks again (18 links, and most of CI's test build). The
//! interrupt tests keep a binary of their own (they raise the process's one interrupt
//! flag), as does `memory_reuse` (it changes the process's allocator).

mod common;

mod batch;
mod butterworth;
mod chunk_invariance;
mod cli;
mod custom_processor;
mod determinism;
mod fuzz;
mod locate;
mod moc_feedback;
mod oracle;
mod parameters;
mod plot;
mod raa;
mod reliability;
mod remote;
mod remote_hostile;
mod stream;
mod view;
