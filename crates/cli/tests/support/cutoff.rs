//! A network path that can be cut: a TCP relay on a loopback port to a server, which, while
//! cut, forwards nothing in either direction and answers new connections with silence (as a
//! firewall that drops a machine's outbound packets does), and on restoring drops the
//! connections the cut left hanging (as the lost state of that firewall does). Stopped and
//! joined when dropped.
#![allow(dead_code)] // each test file uses a part

use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

struct Flags {
    cut: AtomicBool,
    /// Increased on every restore: a connection from an earlier epoch that saw a cut closes.
    epoch: AtomicU64,
    stop: AtomicBool,
}

/// The relay; `port` is where clients connect.
pub struct Cutoff {
    pub port: u16,
    flags: Arc<Flags>,
    accept: Option<JoinHandle<()>>,
}

impl Cutoff {
    /// Relays 127.0.0.1:`port` (a free one) to 127.0.0.1:`server`.
    pub fn start(server: u16) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        listener.set_nonblocking(true).unwrap();
        let port = listener.local_addr().unwrap().port();
        let flags = Arc::new(Flags {
            cut: AtomicBool::new(false),
            epoch: AtomicU64::new(0),
            stop: AtomicBool::new(false),
        });
        let f = flags.clone();
        let accept = std::thread::spawn(move || accept_loop(listener, server, f));
        Cutoff {
            port,
            flags,
            accept: Some(accept),
        }
    }

    /// From now on nothing passes.
    pub fn cut(&self) {
        self.flags.cut.store(true, Ordering::SeqCst);
    }

    /// Traffic passes again; the connections the cut left hanging are dropped.
    pub fn restore(&self) {
        self.flags.epoch.fetch_add(1, Ordering::SeqCst);
        self.flags.cut.store(false, Ordering::SeqCst);
    }
}

impl Drop for Cutoff {
    fn drop(&mut self) {
        self.flags.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.accept.take() {
            let _ = h.join();
        }
    }
}

fn accept_loop(listener: TcpListener, server: u16, flags: Arc<Flags>) {
    let mut pumps = Vec::new();
    while !flags.stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((client, _)) => {
                client.set_nonblocking(false).unwrap();
                let f = flags.clone();
                pumps.push(std::thread::spawn(move || connection(client, server, f)));
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(_) => std::thread::sleep(Duration::from_millis(20)),
        }
    }
    for p in pumps {
        let _ = p.join();
    }
}

/// One client: held silent while cut, then relayed to the server until either side closes, a
/// cut is restored, or the relay stops.
fn connection(client: TcpStream, server: u16, flags: Arc<Flags>) {
    let epoch = flags.epoch.load(Ordering::SeqCst);
    let alive =
        |f: &Flags| !f.stop.load(Ordering::SeqCst) && f.epoch.load(Ordering::SeqCst) == epoch;
    while flags.cut.load(Ordering::SeqCst) {
        if !alive(&flags) {
            return;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let Ok(upstream) = TcpStream::connect(("127.0.0.1", server)) else {
        return;
    };
    let streams = [client, upstream];
    for s in &streams {
        s.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
    }
    let (a, b) = (
        streams[0].try_clone().unwrap(),
        streams[1].try_clone().unwrap(),
    );
    let f = flags.clone();
    let back = std::thread::spawn(move || pump(b, a, &f, epoch));
    pump(
        streams[0].try_clone().unwrap(),
        streams[1].try_clone().unwrap(),
        &flags,
        epoch,
    );
    for s in &streams {
        let _ = s.shutdown(Shutdown::Both);
    }
    let _ = back.join();
}

/// Copies `from` to `to` while the path is open; while cut, reads nothing (the bytes wait in the
/// kernel's buffers, as dropped packets wait for a retransmission that never gets through).
fn pump(mut from: TcpStream, mut to: TcpStream, flags: &Flags, epoch: u64) {
    let mut buf = [0u8; 16 * 1024];
    loop {
        if flags.stop.load(Ordering::SeqCst) || flags.epoch.load(Ordering::SeqCst) != epoch {
            break;
        }
        if flags.cut.load(Ordering::SeqCst) {
            std::thread::sleep(Duration::from_millis(20));
            continue;
        }
        match from.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                if to.write_all(&buf[..n]).is_err() {
                    break;
                }
            }
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => break,
        }
    }
    let _ = from.shutdown(Shutdown::Both);
    let _ = to.shutdown(Shutdown::Both);
}
