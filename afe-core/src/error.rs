//! The error type shared by every crate of the workspace.

use thiserror::Error;

/// Everything that can go wrong when building or running an AFE graph.
///
/// Each message names the offending request, parameter or input and says what would be
/// accepted, so that a user can act on it without reading the source.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// A request name that no processor produces.
    #[error("unknown request '{name}'{hint} (known requests: {known})")]
    UnknownRequest {
        /// The name as given.
        name: String,
        /// Either empty or ` (did you mean 'x'?)` ([`crate::params::did_you_mean`]).
        hint: String,
        /// Comma-separated list of the accepted names.
        known: String,
    },
    /// A request definition that the registry refuses (name taken, dependency or extra
    /// input not registered, a parameter name declared elsewhere with another meaning).
    #[error("cannot register request '{name}': {reason}")]
    RegistrationRefused {
        /// The request's name.
        name: String,
        /// Why, and what to change.
        reason: String,
    },
    /// A parameter name that no processor declares.
    #[error("unknown parameter '{name}'{hint}")]
    UnknownParameter {
        /// The name as given.
        name: String,
        /// Either empty or ` (did you mean 'x'?)`.
        hint: String,
    },
    /// A parameter value of the wrong type or outside its accepted range.
    #[error("invalid value {value} for parameter '{name}': {reason}")]
    InvalidParameter {
        /// AFE parameter name, e.g. `fb_nChannels`.
        name: String,
        /// The value as given, rendered as JSON.
        value: String,
        /// What is accepted instead.
        reason: String,
    },
    /// The input signal cannot be processed (shape, channel count, content).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A binaural representation was requested on a single-channel input.
    #[error("request '{0}' needs a binaural (two-channel) input, but the input is mono")]
    BinauralOnMono(String),
    /// An invalid sampling rate.
    #[error("invalid sampling rate {0} Hz: it must be above 0 and at most 1 MHz")]
    InvalidSampleRate(f64),
    /// A request handle that does not belong to this manager (or was removed).
    #[error("unknown request handle {0}")]
    UnknownHandle(usize),
    /// A processor panicked on a worker thread of the concurrent scheduler (a bug: the
    /// manager is unusable afterwards; the sequential executor gives the same numbers).
    #[error("a processor panicked on a worker thread: this manager can no longer be used; please report it (threads=0 runs the sequential executor)")]
    WorkerPanicked,
    /// The concurrent scheduler waited longer than its watchdog allows (a bug), with the
    /// state of every node.
    #[error("the scheduler stalled: {0}")]
    Stalled(String),
    /// The concurrent scheduler cannot run or was used out of order (a worker thread
    /// cannot start, chunks submitted or collected out of turn).
    #[error("scheduler: {0}")]
    Scheduler(String),
    /// A whole-signal call would hold more intermediate signals than the limit allows
    /// (processors that, as in the AFE, take their whole input at once).
    #[error("processing the signal in one call would hold {need_mb} MB of intermediate signals for {seconds:.1} s of it ({what} take the whole input at once, as in the AFE), over the limit of {limit_mb} MB: feed it in chunks (the AFE's per-chunk semantics: `afe extract --chunk N`, `chunk=` in Python, `Manager::process_chunk`), shorten it, or raise the limit with the environment variable AFE_WHOLE_SIGNAL_LIMIT_MB")]
    WholeSignalTooLarge {
        /// Length of the signal (or of its part read so far) in seconds.
        seconds: f64,
        /// Memory the call would need, in MB.
        need_mb: u64,
        /// The limit, in MB.
        limit_mb: u64,
        /// The processors that need the whole input, e.g. `innerhaircell (ihc_method 'hilbert')`.
        what: String,
    },
    /// A whole-signal call would take more memory than is available (its input, the
    /// intermediate signals it joins, the outputs and the processors' working copies).
    #[error("processing the signal in one call would take about {need} for {seconds:.1} s of it ({what} take the whole input at once, as in the AFE), more than the {available} of memory available: feed it in chunks (the AFE's per-chunk semantics: `afe extract --chunk N`, `chunk=` in Python, `Manager::process_chunk`), shorten it, or free memory")]
    WholeSignalOverMemory {
        /// Length of the signal (or of its part read so far) in seconds.
        seconds: f64,
        /// Memory the call would take, e.g. `1.8 GB`.
        need: String,
        /// Memory available, e.g. `0.9 GB`.
        available: String,
        /// The processors that need the whole input.
        what: String,
    },
    /// An allocation sized by the signal's length was refused by the allocator (the
    /// memory ran short after the checks: another process took it, or the estimate
    /// was low).
    #[error("could not allocate {need} for {what}: the memory is short; free memory, shorten the signal, or feed it in chunks (`afe extract --chunk N`, `chunk=` in Python)")]
    AllocationFailed {
        /// The size asked for, e.g. `218.7 MB`.
        need: String,
        /// What it was for, e.g. `the joined output of filterbank`.
        what: String,
    },
    /// An environment variable that sets a limit holds a value it does not accept.
    #[error("the environment variable {variable} is {value:?}: it must be {accepted} (unset it for the default)")]
    BadSetting {
        /// The variable, e.g. `AFE_WORK_LIMIT`.
        variable: &'static str,
        /// Its value as set.
        value: String,
        /// What it accepts, e.g. `a positive number of values per second`.
        accepted: &'static str,
    },
    /// The outputs of a whole signal would not fit the memory available (see
    /// `afe::memory`).
    #[error("keeping the outputs would take {need}, more than the {available} of memory available: {WAYS_OUT}")]
    OutputsTooLarge {
        /// Memory the outputs would take, e.g. `7.2 GB`.
        need: String,
        /// Memory available, e.g. `3.9 GB`.
        available: String,
    },
    /// A request whose parameters would make the graph compute or write more values per
    /// second of signal than a limit allows (see `afe_graph::work`).
    #[error("{0}")]
    TooMuchWork(Box<WorkRefusal>),
    /// Stopped on request (SIGINT or SIGTERM, Ctrl-C in Python) before the input's end.
    #[error("interrupted before the end of the input")]
    Interrupted,
}

/// The details of [`Error::TooMuchWork`].
#[derive(Debug, Clone, PartialEq)]
pub struct WorkRefusal {
    /// The request placed.
    pub request: String,
    /// `compute` (every value, the work limit) or `write` (the outputs, the output limit).
    pub what: &'static str,
    /// The graph's estimate with the request, values per second of signal.
    pub per_second: f64,
    /// The processor of the graph that computes or writes the most.
    pub heaviest: String,
    /// Its share, values per second of signal.
    pub heaviest_per_second: f64,
    /// The limit, values per second of signal.
    pub limit: f64,
    /// The environment variable that moves the limit.
    pub variable: &'static str,
    /// The parameters the request set, as `; parameters set: a=1, b=2`, or empty.
    pub set: String,
}

impl std::fmt::Display for WorkRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "request '{}' would make the graph {} about {:.1e} values per second of signal \
             (its {} alone {:.1e}), over the limit of {:.1e}{}: a longer hop, a shorter \
             window, fewer channels, lags or bins lower it, or raise the limit with the \
             environment variable {} (values per second)",
            self.request,
            self.what,
            self.per_second,
            self.heaviest,
            self.heaviest_per_second,
            self.limit,
            self.set,
            self.variable
        )
    }
}

/// What to do about outputs too large for the memory: the end of
/// [`Error::OutputsTooLarge`]'s message and of `afe::memory`'s warning.
pub const WAYS_OUT: &str = "store them as float32 (`dtype=\"float32\"`, `--dtype f32`), ask for \
    fewer requests, write them to a store file by file (`afe.batch`, `afe batch`), or stream them \
    (`afe.stream`, `afe stream`)";

impl Error {
    /// An [`Error::InvalidParameter`] for parameter `name` (its AFE name): `value` as the
    /// caller renders it (a number, a list, or a short account such as `[2000 values]`)
    /// and `reason`, what is accepted instead.
    pub fn invalid(
        name: impl Into<String>,
        value: impl std::fmt::Display,
        reason: impl Into<String>,
    ) -> Self {
        Error::InvalidParameter {
            name: name.into(),
            value: value.to_string(),
            reason: reason.into(),
        }
    }
}

/// Shorthand for results carrying [`enum@Error`].
pub type Result<T> = std::result::Result<T, Error>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_names_the_parameter_the_value_and_what_is_accepted() {
        let e = Error::invalid("fb_nChannels", 0, "must be at least 1");
        assert_eq!(
            e.to_string(),
            "invalid value 0 for parameter 'fb_nChannels': must be at least 1"
        );
        let shortest = Error::invalid("x", format_args!("{:?}", 1e308), String::from("r"));
        assert!(matches!(shortest, Error::InvalidParameter { value, .. } if value == "1e308"));
    }
}
