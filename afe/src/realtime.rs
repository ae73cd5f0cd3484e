//! Hard real time for live streams (`afe stream --rt`): the processing thread, and the
//! threads it starts afterwards (the scheduler's workers and the source's feeder inherit
//! its policy), run under SCHED_FIFO, and the process's memory is locked so that no page
//! fault stalls a block. Each step reports why it failed (usually: no privilege).

use thread_priority::{
    set_thread_priority_and_policy, thread_native_id, RealtimeThreadSchedulePolicy, ThreadPriority,
    ThreadPriorityValue, ThreadSchedulePolicy,
};

/// Priority asked for, on the 0–99 scale (mapped onto SCHED_FIFO's 1–99): above the
/// desktop and most daemons, below the kernel's own real-time threads.
const PRIORITY: u8 = 50;

/// What `--rt` obtained.
#[derive(Debug, Clone, PartialEq)]
pub struct Realtime {
    /// `Ok`: SCHED_FIFO was set; `Err`: why not.
    pub fifo: Result<(), String>,
    /// `Ok`: all current and future pages are locked in memory; `Err`: why not.
    pub locked: Result<(), String>,
}

impl Realtime {
    /// One line for people: what was obtained, and what to do about what was not.
    pub fn describe(&self) -> String {
        let fifo = match &self.fifo {
            Ok(()) => format!("SCHED_FIFO priority {PRIORITY}"),
            Err(e) => format!(
                "no SCHED_FIFO ({e}: run as root, grant CAP_SYS_NICE, or raise 'rtprio' in /etc/security/limits.conf)"
            ),
        };
        let locked = match &self.locked {
            Ok(()) => "memory locked".to_string(),
            Err(e) => format!(
                "memory not locked ({e}: run as root, grant CAP_IPC_LOCK, or raise 'memlock')"
            ),
        };
        format!("{fifo}; {locked}")
    }

    /// Whether everything asked for was obtained.
    pub fn complete(&self) -> bool {
        self.fifo.is_ok() && self.locked.is_ok()
    }
}

/// Asks for real-time scheduling of the calling thread and locks the process's memory.
pub fn enable() -> Realtime {
    let fifo = ThreadPriorityValue::try_from(PRIORITY)
        .map_err(|e| e.to_string())
        .and_then(|p| {
            set_thread_priority_and_policy(
                thread_native_id(),
                ThreadPriority::Crossplatform(p),
                ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
            )
            .map_err(|e| format!("{e:?}"))
        });
    let locked = nix::sys::mman::mlockall(
        nix::sys::mman::MlockAllFlags::MCL_CURRENT | nix::sys::mman::MlockAllFlags::MCL_FUTURE,
    )
    .map_err(|e| e.desc().to_string());
    Realtime { fifo, locked }
}
