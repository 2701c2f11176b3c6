//! The one way a process hosts the service: `truepos run`, the HAL component and its timing
//! benchmark all start it here, so they share one set of defaults.
//!
//! [`ServiceHost`] takes the machine, the model entries, the sources and sinks, one
//! [`ServiceConfig`] and an optional log file; [`ServiceHost::start`] builds the [`Service`]
//! and, with a log file, starts its [`Logger`] (committing every [`log::COMMIT_EVERY`]) and
//! returns both as a [`Running`] service. [`Running::stop`] is the one way to stop it: the
//! logger writes what is still queued and stops, and its health over the run comes back with
//! the service.
//!
//! Every model passes [`crate::admission`] here, at start and at every hot reload,
//! so no host can forget it: a model implausible for the machine, or too slow for the cycle
//! period ([`ServiceHost::period_s`]), never reaches the service.
//!
//! Starting creates only the logger's thread, so a caller that pins CPUs or raises priorities
//! does so after [`ServiceHost::start`] (the thread inherits neither) or keeps it off the
//! cycle's CPU before.

mod reload;

use std::path::PathBuf;

use reload::Reloader;
pub use reload::{ModelLoader, ReloadSetup, POLL as RELOAD_POLL};

use crate::admission;
use crate::config::MachineConfig;
use crate::log::{self, LogError, LogHealth, LogSetup, Logger};
use crate::model_set::ModelEntry;
use crate::{Service, ServiceConfig, Sink, Source};

/// The cycle period assumed unless [`ServiceHost::period_s`] says otherwise: LinuxCNC's servo
/// thread, the shortest period the project runs at.
pub const DEFAULT_PERIOD_S: f64 = 0.001;

/// What the service is started with; [`ServiceHost::start`] starts it.
pub struct ServiceHost {
    machine: MachineConfig,
    models: Vec<ModelEntry>,
    sources: Vec<Box<dyn Source>>,
    sinks: Vec<Box<dyn Sink>>,
    config: ServiceConfig,
    log: Option<PathBuf>,
    reload: Option<ReloadSetup>,
    period_s: f64,
}

/// Why a service did not start; nothing has run then.
#[derive(Debug)]
pub enum StartError {
    /// A model of the set is refused by [`admission`]: the words name the model, the axis, the
    /// figure and the limit.
    Refused(String),
    /// The log cannot be opened or is refused, or the reload thread cannot start.
    Log(LogError),
}

impl std::fmt::Display for StartError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Refused(why) => f.write_str(why),
            Self::Log(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for StartError {}

impl From<LogError> for StartError {
    fn from(e: LogError) -> Self {
        Self::Log(e)
    }
}

impl ServiceHost {
    /// A machine and its model set (in order of preference), no sources, no sinks, the default
    /// [`ServiceConfig`] and no log.
    pub fn new(machine: MachineConfig, models: Vec<ModelEntry>) -> Self {
        Self {
            machine,
            models,
            sources: Vec::new(),
            sinks: Vec::new(),
            config: ServiceConfig::default(),
            log: None,
            reload: None,
            period_s: DEFAULT_PERIOD_S,
        }
    }

    /// The period at which the caller runs cycles, s (default [`DEFAULT_PERIOD_S`]): every
    /// model's evaluation must fit it ([`admission::admit`]).
    pub fn period_s(mut self, period_s: f64) -> Self {
        self.period_s = period_s;
        self
    }

    /// Hot reload of the model files (default: none): see [`Running::request_reload`] and
    /// [`Running::poll_reload`].
    pub fn reload(mut self, setup: Option<ReloadSetup>) -> Self {
        self.reload = setup;
        self
    }

    /// Adds a source (read every cycle in the order added).
    pub fn source(mut self, source: Box<dyn Source>) -> Self {
        self.sources.push(source);
        self
    }

    /// Adds sources.
    pub fn sources(mut self, sources: impl IntoIterator<Item = Box<dyn Source>>) -> Self {
        self.sources.extend(sources);
        self
    }

    /// Adds a sink (written every cycle in the order added).
    pub fn sink(mut self, sink: Box<dyn Sink>) -> Self {
        self.sinks.push(sink);
        self
    }

    /// Adds sinks.
    pub fn sinks(mut self, sinks: impl IntoIterator<Item = Box<dyn Sink>>) -> Self {
        self.sinks.extend(sinks);
        self
    }

    /// The settings of the cycle (default: [`ServiceConfig::default`]).
    pub fn config(mut self, config: ServiceConfig) -> Self {
        self.config = config;
        self
    }

    /// The SQLite log, if any (default: none).
    pub fn log(mut self, path: Option<PathBuf>) -> Self {
        self.log = path;
        self
    }

    /// Admits every model, builds the service and starts its logger (and the reload thread, if
    /// asked; each reloaded model is admitted on that thread before the service sees it). Fails
    /// if a model is refused, the log cannot be opened or is refused ([`Logger::start`]), or
    /// the reload thread cannot start; nothing has run then.
    pub fn start(self) -> Result<Running, StartError> {
        if !(self.period_s.is_finite() && self.period_s > 0.0 && self.period_s <= 3600.0) {
            return Err(StartError::Refused(format!(
                "cycle period {} s: expected a time above 0 and at most an hour",
                self.period_s
            )));
        }
        admission::admit_set(&self.models, &self.machine, self.period_s)
            .map_err(StartError::Refused)?;
        let reload = self
            .reload
            .map(|setup| admitted(setup, self.machine.clone(), self.period_s));
        let models: Vec<String> = self.models.iter().map(|e| e.name.clone()).collect();
        let sources: Vec<String> = self.sources.iter().map(|s| s.name().to_string()).collect();
        let sinks: Vec<String> = self.sinks.iter().map(|s| s.name().to_string()).collect();
        let service = Service::new(
            self.machine,
            self.models,
            self.sources,
            self.sinks,
            self.config,
        );
        let logger = match &self.log {
            Some(path) => Some(Logger::start_with_probes(
                LogSetup {
                    path,
                    machine: service.machine(),
                    models: models.clone(),
                    sources,
                    sinks,
                    paths: service.path_states().len(),
                    commit_every: log::COMMIT_EVERY,
                },
                service.events(),
                service.records(),
                service.probes(),
            )?),
            None => None,
        };
        let reloader = match reload {
            Some(setup) => Some(Reloader::start(setup).map_err(|e| LogError {
                file: PathBuf::from("(model reload)"),
                message: format!("cannot start the reload thread: {e}"),
            })?),
            None => None,
        };
        Ok(Running {
            service,
            logger,
            generations: vec![1; models.len()],
            models,
            reloader,
        })
    }
}

/// The reload setup with every loaded model admitted before it leaves the reload thread.
fn admitted(setup: ReloadSetup, machine: MachineConfig, period_s: f64) -> ReloadSetup {
    let load = setup.loader;
    ReloadSetup {
        loader: Box::new(move |path| {
            let entry = load(path)?;
            admission::admit(&entry, &machine, period_s)?;
            Ok(entry)
        }),
        ..setup
    }
}

/// A started service and its logger; stop it with [`Running::stop`].
pub struct Running {
    /// The service: the caller runs its cycles.
    pub service: Service,
    logger: Option<Logger>,
    models: Vec<String>,
    /// Per model of the set: 1 as started, one more for every reload applied.
    generations: Vec<u64>,
    reloader: Option<Reloader>,
}

/// What [`Running::poll_reload`] did with the files the reload thread loaded.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReloadReport {
    /// Models replaced: (index in the set, file).
    pub reloaded: Vec<(usize, PathBuf)>,
    /// Files that did not load or were refused, with the reason; the running model stays.
    pub failed: Vec<(PathBuf, String)>,
}

impl Running {
    /// Asks the reload thread to reload every model file (a no-op without
    /// [`ServiceHost::reload`]). Sets a flag: nothing waits.
    pub fn request_reload(&self) {
        if let Some(r) = &self.reloader {
            r.request();
        }
    }

    /// Hands the models the reload thread has loaded to the service (between cycles: call it
    /// from the loop, not inside a cycle) and logs a `model-reloaded` or `model-reload-failed`
    /// event naming the file, and the reason of a failure. Returns `None` when nothing arrived
    /// (one pop of a lock-free queue, no allocation). A model that fails to load or is refused
    /// ([`Service::replace_model`]) leaves the running one untouched.
    pub fn poll_reload(&mut self) -> Option<ReloadReport> {
        let r = self.reloader.as_ref()?;
        let first = r.results.pop()?;
        let mut report = ReloadReport::default();
        let mut next = Some(first);
        while let Some(l) = next {
            let time_s = self.service.frame().time_s;
            let name = self
                .models
                .get(l.model)
                .cloned()
                .unwrap_or_else(|| format!("#{}", l.model));
            let applied = l.entry.and_then(|e| self.service.replace_model(l.model, e));
            let file = l.file.display().to_string();
            match applied {
                Ok(old) => {
                    // Dropped on the reload thread; if its queue is full, here.
                    let _ = r.garbage.push(old);
                    if let Some(log) = &self.logger {
                        log.note(time_s, "model-reloaded", name, file);
                    }
                    if let Some(g) = self.generations.get_mut(l.model) {
                        *g += 1;
                    }
                    report.reloaded.push((l.model, l.file));
                }
                Err(why) => {
                    let why = if why.contains(&file) {
                        why
                    } else {
                        format!("{file}: {why}")
                    };
                    if let Some(log) = &self.logger {
                        log.note(
                            time_s,
                            "model-reload-failed",
                            name,
                            format!("{why}; the running model stays"),
                        );
                    }
                    report.failed.push((l.file, why));
                }
            }
            next = r.results.pop();
        }
        Some(report)
    }

    /// Names of the models of the set, in set order.
    pub fn model_names(&self) -> &[String] {
        &self.models
    }

    /// Per model of the set, in set order, its generation: 1 as started, one more for every
    /// reload applied.
    pub fn model_generations(&self) -> &[u64] {
        &self.generations
    }

    /// How the log is doing now (`None`: no log).
    pub fn log_health(&self) -> Option<LogHealth> {
        self.logger.as_ref().map(Logger::health)
    }

    /// The log's figures without a lock or an allocation ([`Logger::figures`]): whether it
    /// fails, records pending, records dropped; `None` without a log.
    pub fn log_figures(&self) -> Option<(bool, u64, u64)> {
        self.logger.as_ref().map(Logger::figures)
    }

    /// Stops the service: the logger writes what is still queued and stops. Returns the service
    /// (for its figures) and how the log did.
    pub fn stop(self) -> Stopped {
        Stopped {
            service: self.service,
            log: self.logger.map(Logger::stop_with_health),
        }
    }
}

/// A stopped service.
pub struct Stopped {
    /// The service, after its last cycle.
    pub service: Service,
    /// The logger's last write (an error if it never took the queue) and its health over the
    /// run; `None` without a log.
    pub log: Option<(Result<(), LogError>, LogHealth)>,
}
