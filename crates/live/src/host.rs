//! The live view beside a host's cycle loop (`truepos run --http`, `truepos-hal run --http`):
//! the address and the token checked before anything starts ([`HttpArgs::check`]), the server
//! started for a started service ([`Live::start`]), and the board published from the loop
//! between cycles ([`Live::publish`]).

use std::net::{SocketAddr, ToSocketAddrs};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use truepos_runtime::live::{Board, HostFigures, Layout, LogFigures, PUBLISH_EVERY};
use truepos_runtime::{log, Running};

use crate::{access, Info, LiveServer, LiveSetup};

/// How often the log's health is read for the board (it takes the logger's lock).
const LOG_HEALTH_EVERY: Duration = Duration::from_secs(1);

/// The checked `--http` options.
#[derive(Debug)]
pub struct HttpArgs {
    pub(crate) addr: SocketAddr,
    pub(crate) token: Option<String>,
}

/// The live view's command-line options as every process running the service takes them
/// (`truepos run`, `truepos-hal run`; feature `clap`), checked by [`HttpOptions::check`].
#[cfg(feature = "clap")]
#[derive(Debug, Clone, Default, clap::Args)]
pub struct HttpOptions {
    /// Serve the live view (page, JSON, Server-Sent Events, Prometheus `/metrics`) on ADDR:
    /// `127.0.0.1:8080`, or a port alone for loopback; port 0 picks a free one. An address
    /// beyond loopback needs a token (TRUEPOS_HTTP_TOKEN or --http-token-file); docs/live_view.md.
    #[arg(long, value_name = "ADDR")]
    pub http: Option<String>,
    /// The live view's token: the first line of FILE (at least 16 characters).
    #[arg(long, value_name = "FILE")]
    pub http_token_file: Option<PathBuf>,
}

#[cfg(feature = "clap")]
impl HttpOptions {
    /// [`HttpArgs::check`] of these options.
    pub fn check(&self) -> Result<Option<HttpArgs>, String> {
        HttpArgs::check(self.http.as_deref(), self.http_token_file.as_deref())
    }
}

/// `ADDR` as `host:port`, or a port alone (then loopback, 127.0.0.1).
fn parse_addr(spec: &str) -> Result<SocketAddr, String> {
    if !spec.is_empty() && spec.bytes().all(|b| b.is_ascii_digit()) {
        let port: u16 = spec
            .parse()
            .map_err(|_| format!("--http {spec}: not a port (0–65535)"))?;
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
    spec.to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| {
            format!(
                "--http {spec}: expected ADDRESS:PORT (127.0.0.1:8080, 0.0.0.0:8080, [::1]:8080) or a port"
            )
        })
}

impl HttpArgs {
    /// Checks `--http` and the token before the service starts: a non-loopback address
    /// without a token is refused here, with what to do.
    pub fn check(http: Option<&str>, token_file: Option<&Path>) -> Result<Option<Self>, String> {
        let Some(spec) = http else {
            if token_file.is_some() {
                return Err("--http-token-file without --http: give --http ADDR too".into());
            }
            return Ok(None);
        };
        let addr = parse_addr(spec)?;
        let env = std::env::var(access::TOKEN_ENV).ok();
        let token = access::token_from(env, token_file)?;
        access::check_bind(addr, token.as_deref())?;
        Ok(Some(Self { addr, token }))
    }
}

/// The running live view and what the loop publishes into it.
pub struct Live {
    server: LiveServer,
    board: Arc<Board>,
    next: Instant,
    next_log: Instant,
    log: Option<LogFigures>,
}

impl Live {
    /// Starts the server for a started service (before its first cycle). Says where it listens
    /// on stderr (`live view on http://ADDR/`), which a test reads.
    /// `model_files`: the files of the set's models in its order (their validation figures are
    /// read from them).
    pub fn start(
        args: HttpArgs,
        host: &Running,
        sources: Vec<String>,
        log_file: Option<&PathBuf>,
        model_files: &[PathBuf],
    ) -> Result<Self, String> {
        let board = Arc::new(Board::new(Layout::of(&host.service)));
        let log = log_file.map(|f| (f.clone(), log::last_rows(f)));
        // Probe events of the runs before this one are not this run's quality.
        let probes_after = log_file
            .and_then(|f| log::read_probes(f).ok())
            .and_then(|t| t.rows.last().map(|r| r.row))
            .unwrap_or(0);
        let info = Info::of(host, sources, log.is_some());
        let server = LiveServer::start(LiveSetup {
            addr: args.addr,
            token: args.token,
            board: Arc::clone(&board),
            info,
            log,
            probes_after,
            model_files: model_files.iter().cloned().map(Some).collect(),
        })?;
        eprintln!("live view on http://{}/", server.addr());
        let now = Instant::now();
        Ok(Self {
            server,
            board,
            next: now,
            next_log: now,
            log: None,
        })
    }

    /// Publishes the service's state after a cycle, at most every [`PUBLISH_EVERY`] of real
    /// time; between those, one clock read and the cycle's work recorded (a few atomics). Call
    /// between cycles, never inside one.
    pub fn publish(&mut self, host: &Running, late_cycles: u64, cycle_work_us: f64) {
        let now = Instant::now();
        // Every cycle's work, for the percentiles the server makes on its own thread.
        self.board.record_work(cycle_work_us, now);
        if now < self.next {
            return;
        }
        self.next = now + PUBLISH_EVERY;
        if now >= self.next_log {
            self.next_log = now + LOG_HEALTH_EVERY;
            // Atomics, not `log_health`: the LinuxCNC component calls this on its real-time
            // thread, which must not take the logger's lock nor allocate.
            self.log = host
                .log_figures()
                .map(|(failing, pending, dropped)| LogFigures {
                    failing,
                    pending,
                    dropped,
                });
        }
        self.board.publish(
            &host.service,
            &HostFigures {
                late_cycles,
                cycle_work_us,
                log: self.log,
                generations: host.model_generations(),
            },
        );
    }

    /// Publishes the last state and stops the server.
    pub fn stop(mut self, host: &Running, late_cycles: u64) {
        self.next = Instant::now();
        self.next_log = self.next;
        self.publish(host, late_cycles, f64::NAN);
        self.server.stop();
    }
}
