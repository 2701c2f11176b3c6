//! The Modbus source: its polling thread and the cycle's view of the values it publishes.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use truepos_model::Machine;

use super::client::ModbusClient;
use super::codec::{decode, DecodeError, Encoding, ModbusError, WordOrder};
use super::config::ModbusConfig;
use super::plan::{plan_reads, split_blocks, ReadBlock};
use truepos_files::InputError;
use truepos_runtime::sources::{
    resolve_address, seconds_since, sleep_unless_stopped, Backoff, BackoffConfig, LinkStatus,
    PolledSource, STOP_LIMIT,
};
use truepos_runtime::SharedChannels;

/// A Modbus TCP source: [`ModbusSource::start`] gives its polling thread to a [`PolledSource`],
/// the cycle's view of the values it publishes.
#[derive(Debug)]
pub struct ModbusSource;

impl ModbusSource {
    /// Starts the polling thread for a checked configuration. `epoch` is the service clock's
    /// zero: stamps are seconds since it.
    pub fn start(
        config: &ModbusConfig,
        machine: &Machine,
        epoch: Instant,
    ) -> Result<PolledSource, InputError> {
        let (targets, spans) = config.resolve(machine)?;
        let peer = resolve_address(&config.address, "modbus.address")?;
        let (poll, timeout) = (config.poll_ms, config.timeout_ms);
        let backoff = config.backoff;
        let blocks = plan_reads(&spans);
        let decoders: Vec<(Encoding, WordOrder)> = config
            .channels
            .iter()
            .map(|c| (c.encoding, c.word_order))
            .collect();
        let name = format!("modbus {}", config.address);
        PolledSource::start(name, targets, STOP_LIMIT, move |link| {
            Poller {
                peer,
                poll: Duration::from_millis(poll),
                timeout: Duration::from_millis(timeout),
                backoff,
                blocks,
                decoders,
                channels: link.channels,
                status: link.status,
                stop: link.stop,
                epoch,
            }
            .run()
        })
    }
}

/// The polling thread.
struct Poller {
    peer: SocketAddr,
    poll: Duration,
    timeout: Duration,
    backoff: BackoffConfig,
    blocks: Vec<ReadBlock>,
    decoders: Vec<(Encoding, WordOrder)>,
    channels: Arc<SharedChannels>,
    status: Arc<LinkStatus>,
    stop: Arc<AtomicBool>,
    epoch: Instant,
}

impl Poller {
    fn run(mut self) {
        let mut backoff = Backoff::new(self.backoff);
        // The last problem reported per block and per channel, so that a lasting one is reported
        // once, not at every poll.
        let mut block_problem: Vec<Option<String>> = vec![None; self.blocks.len()];
        let mut value_problem: Vec<Option<DecodeError>> = vec![None; self.decoders.len()];
        while !self.stop.load(Ordering::Acquire) {
            match ModbusClient::connect(self.peer, self.timeout) {
                Ok(client) => {
                    let mut client = client.stop_on(Arc::clone(&self.stop));
                    backoff.reset();
                    self.status.set_connected(
                        seconds_since(self.epoch),
                        format!("connected to Modbus server {}", self.peer),
                    );
                    match self.poll_until_lost(&mut client, &mut block_problem, &mut value_problem)
                    {
                        None => return,
                        Some(why) => self.status.set_lost(seconds_since(self.epoch), why),
                    }
                }
                Err(e) => self
                    .status
                    .set_lost(seconds_since(self.epoch), e.to_string()),
            }
            if !sleep_unless_stopped(backoff.next_delay(), &self.stop) {
                return;
            }
        }
    }

    /// Polls until the connection is lost (returns why) or the source stops (returns `None`).
    /// A round in which the server refuses a request (an exception) makes the source fail with
    /// that reason until a round is answered in full.
    fn poll_until_lost(
        &mut self,
        client: &mut ModbusClient,
        block_problem: &mut Vec<Option<String>>,
        value_problem: &mut [Option<DecodeError>],
    ) -> Option<String> {
        let mut next = Instant::now();
        let mut failing: Option<String> = None;
        loop {
            let mut split = Vec::new();
            let mut refused: Option<String> = None;
            for (b, block) in self.blocks.iter().enumerate() {
                if self.stop.load(Ordering::Acquire) {
                    return None;
                }
                // The source's name carries the server's address.
                let what = format!(
                    "unit {} function {:02X} registers {}–{}",
                    block.unit,
                    block.kind.function_code(),
                    block.address,
                    u32::from(block.address) + u32::from(block.count) - 1
                );
                match client.read_registers(block.unit, block.kind, block.address, block.count) {
                    Ok(registers) => {
                        block_problem[b] = None;
                        self.publish_block(block, &registers, value_problem);
                    }
                    // A module may refuse a read that spans registers it does not have (between
                    // the ones configured): read the channels of that block one by one.
                    Err(ModbusError::Exception { code: 0x02, .. }) if block.members.len() > 1 => {
                        split.push(b);
                        self.status.bad_data(
                            seconds_since(self.epoch),
                            format!(
                                "Modbus server {} unit {} function {:02X} registers {}–{}: exception 02 \
                                 (illegal data address) to a grouped read; reading its {} channels one by one",
                                self.peer,
                                block.unit,
                                block.kind.function_code(),
                                block.address,
                                u32::from(block.address) + u32::from(block.count) - 1,
                                block.members.len()
                            ),
                        );
                    }
                    Err(e) if e.keeps_connection() => {
                        let why = format!("{what}: {e}");
                        if block_problem[b].as_deref() != Some(why.as_str()) {
                            self.status.bad_data(seconds_since(self.epoch), why.clone());
                            block_problem[b] = Some(why.clone());
                        }
                        refused.get_or_insert(why);
                    }
                    Err(e) => return Some(format!("{what}: {e}")),
                }
            }
            match refused {
                Some(why) if failing.as_deref() != Some(why.as_str()) => {
                    self.status
                        .set_failing(seconds_since(self.epoch), why.clone());
                    failing = Some(why);
                }
                None if failing.is_some() => {
                    failing = None;
                    self.status.set_delivering(
                        seconds_since(self.epoch),
                        format!("Modbus server {} answers every request again", self.peer),
                    );
                }
                _ => {}
            }
            if !split.is_empty() {
                self.blocks = split_blocks(&self.blocks, &split, &self.decoders);
                block_problem.clear();
                block_problem.resize(self.blocks.len(), None);
            }
            next += self.poll;
            let now = Instant::now();
            if next < now {
                next = now; // a slow server: poll again at once, without catching up
            }
            if !sleep_unless_stopped(next - now, &self.stop) {
                return None;
            }
        }
    }

    /// Publishes the values of an answered block, each decoded from its registers, stamped with
    /// the answer's time. An invalid value is published as NaN so that validation rejects it,
    /// and reported once while it lasts.
    fn publish_block(
        &self,
        block: &ReadBlock,
        registers: &[u16],
        value_problem: &mut [Option<DecodeError>],
    ) {
        let now = seconds_since(self.epoch);
        for &(k, offset) in &block.members {
            let (encoding, order) = self.decoders[k];
            let start = usize::from(offset);
            let end = start + usize::from(encoding.registers());
            let value = registers
                .get(start..end)
                .ok_or(DecodeError::WrongCount {
                    expected: end,
                    found: registers.len(),
                })
                .and_then(|r| decode(encoding, order, r));
            match value {
                Ok(x) => {
                    value_problem[k] = None;
                    self.channels.publish(k, x, now);
                }
                Err(e) => {
                    self.channels.publish(k, f64::NAN, now);
                    if value_problem[k] != Some(e) {
                        value_problem[k] = Some(e);
                        self.status.bad_data(
                            now,
                            format!(
                                "Modbus server {} unit {} register {}: {e}",
                                self.peer,
                                block.unit,
                                u32::from(block.address) + u32::from(offset)
                            ),
                        );
                    }
                }
            }
        }
    }
}
