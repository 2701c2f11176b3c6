//! The OPC UA source: a thread reads the configured nodes every `sample_ms` and publishes what
//! is usable; the cycle copies the latest values (atomics only).
//!
//! The same validity rules as every source: a value is published only if its status is Good,
//! it is a number and, scaled, finite. Anything else (Bad or Uncertain status, a string, a NaN)
//! leaves the channel as it was, so its stamp stops advancing and the service's validation
//! declares it stale: a bad reading becomes an invalid input, never a number on an axis. The
//! first such reading of a node is reported (stderr and the link's events), not every read.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use opcua::types::{DataValue, NodeId, ReadValueId, StatusCode, TimestampsToReturn, Variant};
use truepos_files::InputError;
use truepos_runtime::sources::{
    seconds_since, Backoff, LinkStatus, PolledSource, Target, STOP_LIMIT,
};
use truepos_runtime::SharedChannels;

use super::client::{connect, describe, node_id};
use super::config::{Identity, SourceConfig};

/// The OPC UA source: [`OpcUaSource::start`] gives its reading thread to a [`PolledSource`], the
/// cycle's view of the values it publishes.
#[derive(Debug)]
pub struct OpcUaSource;

impl OpcUaSource {
    /// Starts the reading thread for a checked configuration; stamps are seconds since `epoch`
    /// (the service clock's zero).
    pub fn start(
        config: &SourceConfig,
        identity: Identity,
        targets: Vec<Target>,
        epoch: Instant,
    ) -> Result<PolledSource, InputError> {
        let nodes = config
            .channel
            .iter()
            .enumerate()
            .map(|(i, c)| {
                node_id(&c.node)
                    .map_err(|e| InputError::at_key(format!("channel[{}].node", i + 1), e))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let config = config.clone();
        let name = format!("opcua {}", config.connection.endpoint);
        // The thread may be inside a session's close when asked to stop: 2 s more than the rest.
        let limit = STOP_LIMIT + Duration::from_secs(2);
        PolledSource::start(name, targets, limit, move |link| {
            Reader {
                scale: config.channel.iter().map(|c| (c.scale, c.offset)).collect(),
                config,
                identity,
                nodes,
                channels: link.channels,
                status: link.status,
                stop: link.stop,
                epoch,
            }
            .run()
        })
    }
}

struct Reader {
    config: SourceConfig,
    identity: Identity,
    nodes: Vec<NodeId>,
    scale: Vec<(f64, f64)>,
    channels: Arc<SharedChannels>,
    status: Arc<LinkStatus>,
    stop: Arc<AtomicBool>,
    epoch: Instant,
}

/// A node's value as a number the source may publish, or why not.
pub fn usable(v: Option<&DataValue>, scale: f64, offset: f64) -> Result<f64, String> {
    let v = v.ok_or("no value in the answer")?;
    if let Some(s) = v.status.filter(|s| !s.is_good()) {
        return Err(format!("status {}", describe(s)));
    }
    let raw = match v.value.as_ref().ok_or("no value")? {
        Variant::Double(x) => *x,
        Variant::Float(x) => f64::from(*x),
        Variant::Int16(x) => f64::from(*x),
        Variant::UInt16(x) => f64::from(*x),
        Variant::Int32(x) => f64::from(*x),
        Variant::UInt32(x) => f64::from(*x),
        Variant::Int64(x) => *x as f64,
        Variant::UInt64(x) => *x as f64,
        Variant::SByte(x) => f64::from(*x),
        Variant::Byte(x) => f64::from(*x),
        other => return Err(format!("expected a number, found {:?}", other.type_id())),
    };
    let x = raw * scale + offset;
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("expected a finite number, found {raw}"))
    }
}

impl Reader {
    fn run(self) {
        match tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
        {
            Ok(rt) => rt.block_on(self.sessions()),
            Err(e) => self
                .status
                .set_lost(0.0, format!("cannot start the OPC UA runtime: {e}")),
        }
    }

    async fn sleep(&self, d: Duration) {
        let end = Instant::now() + d;
        while !self.stop.load(Ordering::Relaxed) && Instant::now() < end {
            tokio::time::sleep(Duration::from_millis(20).min(end - Instant::now())).await;
        }
    }

    async fn sessions(&self) {
        let conn = &self.config.connection;
        let mut backoff = Backoff::new(conn.backoff);
        let mut said = String::new();
        while !self.stop.load(Ordering::Relaxed) {
            let why = match connect(conn, &self.identity).await {
                Err(why) => why,
                Ok(mut open) => {
                    self.status.set_connected(
                        seconds_since(self.epoch),
                        format!("session open on {}", conn.endpoint),
                    );
                    let (why, delivered) = self.read_loop(&open.session, &open).await;
                    // A session that opens and fails at its first read (a node the server
                    // cannot encode) backs off like a refused connection, not 4 times a second.
                    if delivered {
                        backoff.reset();
                    }
                    let ended = open.ended(conn).await;
                    open.close(Duration::from_millis(conn.timeout_ms)).await;
                    match (why, ended) {
                        (Some(w), Some(r)) => format!("{w}: {r}"),
                        (Some(w), None) => w,
                        (None, _) => return,
                    }
                }
            };
            if why != said {
                eprintln!("{}: {why}", conn.endpoint);
                said = why.clone();
            }
            self.status.set_lost(seconds_since(self.epoch), why);
            self.sleep(backoff.next_delay()).await;
        }
    }

    async fn read_loop(
        &self,
        session: &opcua::client::Session,
        open: &super::client::Open,
    ) -> (Option<String>, bool) {
        let conn = &self.config.connection;
        let mut delivered = false;
        let ids: Vec<ReadValueId> = self.nodes.iter().cloned().map(ReadValueId::from).collect();
        let mut ticker = tokio::time::interval(Duration::from_millis(self.config.sample_ms));
        ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let timeout = Duration::from_millis(conn.timeout_ms);
        let mut bad: Vec<Option<String>> = vec![None; ids.len()];
        loop {
            ticker.tick().await;
            if self.stop.load(Ordering::Relaxed) {
                return (None, delivered);
            }
            if open.lost() {
                return (Some("the session was lost".into()), delivered);
            }
            let values = match tokio::time::timeout(
                timeout,
                session.read(&ids, TimestampsToReturn::Neither, 0.0),
            )
            .await
            {
                Err(_) => {
                    self.status.set_failing(
                        seconds_since(self.epoch),
                        format!("a read got no answer within {} ms", conn.timeout_ms),
                    );
                    continue;
                }
                Ok(Err(e)) if e.status() == StatusCode::BadTimeout => continue,
                Ok(Err(e)) => return (Some(format!("a read failed: {e}")), delivered),
                Ok(Ok(v)) => v,
            };
            let now = seconds_since(self.epoch);
            let mut any = false;
            for (k, (scale, offset)) in self.scale.iter().enumerate() {
                match usable(values.get(k), *scale, *offset) {
                    Ok(x) => {
                        self.channels.publish(k, x, now);
                        bad[k] = None;
                        any = true;
                        delivered = true;
                    }
                    Err(why) => {
                        // The channel fails now (not a number, this cycle) instead of going
                        // stale after max_age_s while counted ok; the reason is the link's event.
                        self.channels.publish(k, f64::NAN, now);
                        if bad[k].as_deref() != Some(why.as_str()) {
                            let msg = format!(
                                "node {}: {why}; the channel is not updated",
                                self.nodes[k]
                            );
                            eprintln!("{}: {msg}", conn.endpoint);
                            self.status.bad_data(now, msg);
                            bad[k] = Some(why);
                        }
                    }
                }
            }
            let failing = self.status.snapshot().failing;
            if !any && !failing {
                self.status
                    .set_failing(now, "no node gives a usable value".into());
            } else if any && failing {
                self.status
                    .set_delivering(now, "values arrive again".into());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_good_finite_numbers_are_published() {
        let good = DataValue::value_only(Variant::Double(21.5));
        assert_eq!(usable(Some(&good), 1.0, 0.0), Ok(21.5));
        assert_eq!(
            usable(Some(&DataValue::value_only(Variant::Int32(215))), 0.1, 0.0)
                .map(|x| (x * 10.0).round()),
            Ok(215.0)
        );
        let nan = DataValue::value_only(Variant::Double(f64::NAN));
        assert!(usable(Some(&nan), 1.0, 0.0).unwrap_err().contains("finite"));
        let mut stale = good.clone();
        stale.status = Some(StatusCode::UncertainLastUsableValue);
        assert!(usable(Some(&stale), 1.0, 0.0)
            .unwrap_err()
            .contains("UncertainLastUsableValue"));
        stale.status = Some(StatusCode::BadCommunicationError);
        assert!(usable(Some(&stale), 1.0, 0.0)
            .unwrap_err()
            .contains("BadCommunicationError"));
        let text = DataValue::value_only(Variant::from("21.5"));
        assert!(usable(Some(&text), 1.0, 0.0)
            .unwrap_err()
            .contains("expected a number"));
        assert!(usable(None, 1.0, 0.0).is_err());
    }
}
