//! Supervision of started nodes, processes or composed threads alike: interrupt, wait with a
//! bound, kill after it, and follow a run until its run-ending node exits, ending it early
//! (with its bag finalized) when another node fails or SIGINT arrives.

use std::os::unix::process::CommandExt as _;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};

/// How long a node interrupted at the end of a run gets to finish before it is killed.
pub const STOP_TIMEOUT: Duration = Duration::from_secs(10);

/// How long the run-ending node (the recorder) gets to finalize its bag after another node
/// failed.
pub const FINALIZE_TIMEOUT: Duration = Duration::from_secs(30);

/// A started node, a process or a composed thread, as the supervisor watches it.
pub trait Started {
    /// The node's name.
    fn name(&self) -> &str;
    /// `None` while it runs; then `Ok` if it succeeded, else what went wrong.
    fn exited(&mut self) -> anyhow::Result<Option<Result<(), String>>>;
    /// Asks it to finish cleanly (the recorder finalizes its bag).
    fn interrupt(&self);
    /// Ends it at once (a process is killed; a thread cannot be, and is left).
    fn kill(&mut self) -> anyhow::Result<()>;
}

/// A node (or any program) running as a child process that dies with this one.
#[derive(Debug)]
pub struct Process {
    /// Its name in messages.
    pub name: String,
    child: Child,
}

impl Process {
    /// Starts `program` with `args`. The child gets SIGTERM (and finalizes, as on Ctrl-C)
    /// if this process dies, even by SIGKILL, so no node outlives its launcher; it starts
    /// with SIGINT's default disposition, whatever this process inherited.
    pub fn spawn(name: &str, program: &Path, args: &[String]) -> anyhow::Result<Self> {
        Self::spawn_env(name, program, args, &[])
    }

    /// As [`Process::spawn`], with `env` set for the child (e.g. its `ROS_DOMAIN_ID`).
    pub fn spawn_env(
        name: &str,
        program: &Path,
        args: &[String],
        env: &[(&str, String)],
    ) -> anyhow::Result<Self> {
        let mut command = Command::new(program);
        command.args(args).stdin(Stdio::null());
        command.envs(env.iter().map(|(k, v)| (k, v)));
        // SAFETY: prctl and signal are async-signal-safe and touch only the child being
        // started.
        unsafe {
            command.pre_exec(|| {
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                // The run is stopped by SIGINT, so every node must be able to take it, even
                // when this launcher inherited it ignored (a background job of a
                // non-interactive shell, nohup): a shell-script node cannot trap a signal
                // ignored on entry.
                if libc::signal(libc::SIGINT, libc::SIG_DFL) == libc::SIG_ERR {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
        let child = command
            .spawn()
            .with_context(|| format!("starting {name} ({})", program.display()))?;
        Ok(Self {
            name: name.to_owned(),
            child,
        })
    }

    /// The child's process id.
    pub fn id(&self) -> u32 {
        self.child.id()
    }
}

impl Started for Process {
    fn name(&self) -> &str {
        &self.name
    }

    fn exited(&mut self) -> anyhow::Result<Option<Result<(), String>>> {
        Ok(self.child.try_wait()?.map(|status| match status.success() {
            true => Ok(()),
            false => Err(status.to_string()),
        }))
    }

    fn interrupt(&self) {
        // SIGINT lets a node finish cleanly (the recorder finalizes its bag).
        // SAFETY: kill(2) on a child we started and have not reaped.
        unsafe {
            libc::kill(self.child.id() as libc::pid_t, libc::SIGINT);
        }
    }

    fn kill(&mut self) -> anyhow::Result<()> {
        self.child.kill()?;
        self.child.wait()?;
        Ok(())
    }
}

/// Waits up to `limit` for `node` to exit; returns whether it did.
pub fn wait_for_exit<N: Started>(node: &mut N, limit: Duration) -> anyhow::Result<bool> {
    let start = Instant::now();
    loop {
        if node.exited()?.is_some() {
            return Ok(true);
        }
        if start.elapsed() > limit {
            return Ok(false);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Interrupts every node still running and waits up to `limit` for each to finish, then
/// kills it.
pub fn stop_all<N: Started>(nodes: &mut [N], limit: Duration) -> anyhow::Result<()> {
    for node in nodes.iter_mut() {
        if node.exited()?.is_none() {
            node.interrupt();
        }
    }
    for node in nodes {
        if !wait_for_exit(node, limit)? {
            tracing::warn!("{} did not stop within {limit:?}; killing it", node.name());
            node.kill()?;
        }
    }
    Ok(())
}

/// Follows a run until `ends_run` (the recorder) exits, calling `tick` every 50 ms (the
/// launcher's progress). `stop` (SIGINT) interrupts it; another node failing interrupts it
/// too, waits up to [`FINALIZE_TIMEOUT`] for its bag, and fails naming that node. Gives
/// the run-ending node's outcome; the other nodes are left to the caller.
pub fn follow<N: Started>(
    ends_run: &mut N,
    others: &mut [N],
    stop: &AtomicBool,
    tick: &mut dyn FnMut(),
) -> anyhow::Result<Result<(), String>> {
    let mut interrupted = false;
    loop {
        tick();
        if let Some(outcome) = ends_run.exited()? {
            return Ok(outcome);
        }
        if stop.load(Ordering::SeqCst) && !interrupted {
            ends_run.interrupt();
            interrupted = true;
        }
        for other in others.iter_mut() {
            if let Some(Err(failure)) = other.exited()? {
                ends_run.interrupt();
                wait_for_exit(ends_run, FINALIZE_TIMEOUT)?;
                bail!(
                    "{} failed ({failure}); the recorder finalized the bag with the steps it had",
                    other.name()
                );
            }
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Waits for every one of `nodes` (whole launches, e.g. the shards of a run); when one
/// fails, interrupts the others (each finalizes its bag) and fails naming it.
pub fn wait_all<N: Started>(nodes: &mut [N]) -> anyhow::Result<()> {
    let mut failed = None;
    loop {
        let mut running = 0;
        for node in nodes.iter_mut() {
            match node.exited()? {
                None => running += 1,
                Some(Err(status)) if failed.is_none() => {
                    failed = Some(format!("{} failed ({status})", node.name()));
                }
                Some(_) => {}
            }
        }
        if running == 0 {
            break;
        }
        if failed.is_some() {
            for node in nodes.iter_mut() {
                if node.exited()?.is_none() {
                    node.interrupt();
                }
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    match failed {
        Some(why) => bail!("{why}; the others stopped and finalized their bags"),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stand-in node: a shell that sets its signal handling (`trap`), says it is ready,
    /// then runs `body`. Returns once it is ready, so a signal never meets a shell that
    /// has not set its trap yet.
    fn node(dir: &tempfile::TempDir, name: &str, trap: &str, body: &str) -> Process {
        let ready = dir.path().join(format!("{name}.ready"));
        let script = format!("{trap}; : > '{}'; {body}", ready.display());
        let process = Process::spawn(name, Path::new("/bin/sh"), &["-c".into(), script]).unwrap();
        while !ready.exists() {
            std::thread::sleep(Duration::from_millis(5));
        }
        process
    }

    /// Exits 0 on SIGINT (as a node that finalizes its bag), else runs on; its sleeps are
    /// short, so none outlives it by more than 50 ms.
    fn until_sigint(dir: &tempfile::TempDir, name: &str) -> Process {
        node(
            dir,
            name,
            "trap 'exit 0' INT",
            "while :; do sleep 0.05; done",
        )
    }

    #[test]
    fn a_node_that_dies_ends_the_run_and_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let mut ends_run = until_sigint(&dir, "recorder");
        let mut others = vec![node(&dir, "babbler", "true", "sleep 0.2; exit 3")];
        let stop = AtomicBool::new(false);
        let err = follow(&mut ends_run, &mut others, &stop, &mut || {}).unwrap_err();
        assert!(
            err.to_string().contains("babbler failed (exit status: 3)"),
            "{err}"
        );
        assert_eq!(
            ends_run.exited().unwrap(),
            Some(Ok(())),
            "the recorder was interrupted and finalized"
        );
    }

    #[test]
    fn sigint_interrupts_the_run_ending_node_and_gives_its_outcome() {
        let dir = tempfile::tempdir().unwrap();
        let mut ends_run = until_sigint(&dir, "recorder");
        let mut others = vec![until_sigint(&dir, "sim")];
        let stop = AtomicBool::new(false);
        let mut ticks = 0;
        let outcome = follow(&mut ends_run, &mut others, &stop, &mut || {
            ticks += 1;
            if ticks == 4 {
                stop.store(true, Ordering::SeqCst);
            }
        })
        .unwrap();
        assert_eq!(outcome, Ok(()));
        assert_eq!(
            others[0].exited().unwrap(),
            None,
            "the others are the caller's"
        );
        stop_all(&mut others, Duration::from_secs(30)).unwrap();
        assert_eq!(others[0].exited().unwrap(), Some(Ok(())));
    }

    #[test]
    fn a_node_that_ignores_sigint_is_killed_after_the_timeout() {
        let dir = tempfile::tempdir().unwrap();
        let mut nodes = vec![node(
            &dir,
            "stubborn",
            "trap '' INT",
            "while :; do sleep 0.05; done",
        )];
        let limit = Duration::from_millis(300);
        let started = Instant::now();
        stop_all(&mut nodes, limit).unwrap();
        assert!(started.elapsed() >= limit, "killed before its time was up");
        let outcome = nodes[0].exited().unwrap();
        assert!(
            matches!(&outcome, Some(Err(status)) if status.contains("SIGKILL")),
            "{outcome:?}"
        );
    }

    #[test]
    fn a_failed_shard_stops_the_others_and_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let mut shards = vec![
            until_sigint(&dir, "shard 0"),
            node(&dir, "shard 1", "true", "sleep 0.2; exit 1"),
        ];
        let err = wait_all(&mut shards).unwrap_err();
        assert!(err.to_string().starts_with("shard 1 failed"), "{err}");
        assert_eq!(shards[0].exited().unwrap(), Some(Ok(())));
    }

    #[test]
    fn a_missing_program_is_an_error_naming_it() {
        let err = Process::spawn("ghost", Path::new("/nonexistent/ghost"), &[]).unwrap_err();
        assert!(
            format!("{err:#}").contains("starting ghost (/nonexistent/ghost)"),
            "{err:#}"
        );
    }
}
