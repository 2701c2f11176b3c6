//! The fleet's page: `truepos fleet status --http ADDR` serves the fleet store's status per
//! machine — what `truepos fleet status` prints — as a page that reads it again every
//! [`REFRESH_S`] seconds (`/`) and as JSON (`/api/fleet`), on the same bounded server and with
//! the same access rules as a service's live view (loopback by default, a token beyond).
//!
//! ```no_run
//! use std::sync::Arc;
//! use truepos_live::fleet::FleetServer;
//! use truepos_live::host::HttpArgs;
//! let args = HttpArgs::check(Some("127.0.0.1:8090"), None).unwrap().unwrap();
//! let status = Arc::new(|| Ok(serde_json::json!({"machines": []})));
//! let server = FleetServer::start(args, status).unwrap();
//! println!("fleet view on http://{}/", server.addr());
//! ```

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use serde_json::{json, Value};

use crate::host::HttpArgs;
use crate::http::{Request, Server};
use crate::{gate, respond, respond_json, STACK_BYTES};

/// The page, embedded in the binary (HTML, CSS and JavaScript written here; nothing fetched).
pub const FLEET_PAGE: &str = include_str!("fleet.html");

/// How often the page reads the status again, s (the page's constant is the same figure).
pub const REFRESH_S: u64 = 5;

/// Where the status comes from: asked once per `/api/fleet` request, on that request's thread;
/// an error is answered 503 with its text.
pub type Status = dyn Fn() -> Result<Value, String> + Send + Sync;

/// The running fleet page.
pub struct FleetServer {
    server: Server,
}

impl FleetServer {
    /// Starts serving on the checked address.
    pub fn start(args: HttpArgs, status: Arc<Status>) -> Result<Self, String> {
        let token = args.token.clone();
        let handler = Arc::new(move |rq: Request| handle(rq, token.as_deref(), &*status));
        let server = Server::start(args.addr, STACK_BYTES, handler)
            .map_err(|e| format!("--http {}: {e}", args.addr))?;
        Ok(Self { server })
    }

    /// Where it listens.
    pub fn addr(&self) -> SocketAddr {
        self.server.addr()
    }

    /// Stops serving; a request being answered has a second to finish.
    pub fn stop(mut self) {
        self.server.stop(Duration::from_secs(1));
    }
}

fn handle(rq: Request, token: Option<&str>, status: &Status) {
    let Some(rq) = gate(rq, token) else {
        return;
    };
    let path = rq.url().split('?').next().unwrap_or("").to_string();
    match path.as_str() {
        "/" | "/index.html" => respond(rq, 200, "text/html; charset=utf-8", FLEET_PAGE.into()),
        "/api/fleet" => match status() {
            Ok(v) => respond_json(rq, 200, &v),
            Err(e) => respond_json(rq, 503, &json!({ "error": e })),
        },
        _ => respond(
            rq,
            404,
            "text/plain; charset=utf-8",
            format!("no such page: {path}\n"),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Read, Write};
    use std::net::TcpStream;

    fn get(addr: SocketAddr, target: &str) -> String {
        let mut s = TcpStream::connect(addr).unwrap();
        write!(s, "GET {target} HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
        let mut out = String::new();
        s.read_to_string(&mut out).unwrap();
        out
    }

    #[test]
    fn the_page_and_the_status_are_served_and_a_failing_store_is_a_503() {
        let args = HttpArgs::check(Some("127.0.0.1:0"), None).unwrap().unwrap();
        let calls = Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let c = Arc::clone(&calls);
        let status: Arc<Status> =
            Arc::new(
                move || match c.fetch_add(1, std::sync::atomic::Ordering::SeqCst) {
                    0 => Ok(json!({"machines": [{"machine": "vmc-1", "online": true}]})),
                    _ => Err("PostgreSQL: connection refused".into()),
                },
            );
        let server = FleetServer::start(args, status).unwrap();
        let a = server.addr();
        let page = get(a, "/");
        assert!(
            page.starts_with("HTTP/1.1 200") && page.contains("/api/fleet"),
            "{page}"
        );
        let ok = get(a, "/api/fleet");
        assert!(
            ok.starts_with("HTTP/1.1 200") && ok.contains("\"vmc-1\""),
            "{ok}"
        );
        let down = get(a, "/api/fleet");
        assert!(
            down.starts_with("HTTP/1.1 503") && down.contains("connection refused"),
            "{down}"
        );
        assert!(get(a, "/api/state").starts_with("HTTP/1.1 404"));
        server.stop();
    }
}
