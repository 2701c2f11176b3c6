//! Opening a session: the client's certificate and trust list, the endpoint matching the
//! configured security, the identity, and errors a person can act on.

use std::str::FromStr;
use std::sync::Arc;
use std::time::Duration;

use opcua::client::{ClientBuilder, IdentityToken, Session};
use opcua::crypto::SecurityPolicy;
use opcua::types::{EndpointDescription, MessageSecurityMode, NodeId, StatusCode};
use tokio::task::JoinHandle;

use super::config::{Connection, Identity, Mode, Policy};

/// An open session and the task that drives it (ends when the connection is lost).
pub struct Open {
    /// The session.
    pub session: Arc<Session>,
    /// Its event loop.
    pub driver: JoinHandle<StatusCode>,
}

impl Open {
    /// Closes the session (bounded by `timeout`) and stops its driver.
    pub async fn close(self, timeout: Duration) {
        let _ = tokio::time::timeout(timeout, self.session.disconnect()).await;
        self.driver.abort();
    }

    /// Whether the connection is gone.
    pub fn lost(&self) -> bool {
        self.driver.is_finished()
    }

    /// Why the connection ended, once it has (the stack's status, explained as at connect: a
    /// server certificate that changed names the trust list); `None` while it runs.
    pub async fn ended(&mut self, conn: &Connection) -> Option<String> {
        if !self.driver.is_finished() {
            return None;
        }
        Some(match (&mut self.driver).await {
            Ok(status) => explain(conn, status),
            Err(e) => format!("the session's task ended: {e}"),
        })
    }
}

/// A status that ended or refused a session, with what to do about it.
fn explain(conn: &Connection, s: StatusCode) -> String {
    let name = s.sub_code().name();
    if s == StatusCode::BadCertificateUntrusted || s == StatusCode::BadSecurityChecksFailed {
        format!(
            "{}; the server's certificate is not in the trust list {} (it was put into {} for \
             inspection: if it is your control's, move it into the trust list)",
            describe(s),
            conn.pki_dir.join("trusted").display(),
            conn.pki_dir.join("rejected").display()
        )
    } else if name.starts_with("BadCertificate") {
        format!("{}; the server's certificate is refused", describe(s))
    } else if s == StatusCode::BadUserAccessDenied
        || s == StatusCode::BadIdentityTokenRejected
        || s == StatusCode::BadIdentityTokenInvalid
    {
        format!(
            "{}; check the user and password (and that the user may open a session)",
            describe(s)
        )
    } else {
        describe(s)
    }
}

/// A configured node id, checked again by the stack's own parser.
pub fn node_id(text: &str) -> Result<NodeId, String> {
    NodeId::from_str(text).map_err(|s| format!("node `{text}`: {s}"))
}

/// What a status code means, for a person: its name and the standard's description.
pub fn describe(s: StatusCode) -> String {
    format!("{s} ({})", s.sub_code().description())
}

/// Opens a session as configured. Errors say what to do: a server certificate missing from
/// the trust list names the directory to put it into.
pub async fn connect(conn: &Connection, identity: &Identity) -> Result<Open, String> {
    let timeout = Duration::from_millis(conn.timeout_ms);
    let mut client = ClientBuilder::new()
        .application_name("truepos")
        .application_uri("urn:truepos:client")
        .product_uri("urn:truepos")
        .pki_dir(&conn.pki_dir)
        .create_sample_keypair(true)
        // The trust list decides: a server whose certificate is not in `trusted/` is refused.
        .trust_server_certs(false)
        .verify_server_certs(true)
        // Reconnection is ours (backoff, a new session, the written values read back).
        .session_retry_limit(0)
        .request_timeout(timeout)
        .keep_alive_interval(Duration::from_millis(conn.timeout_ms.max(500)))
        .client()
        .map_err(|e| format!("the OPC UA client configuration: {}", e.join("; ")))?;
    let (policy, mode) = match (conn.security_policy, conn.security_mode) {
        (Policy::None, _) => (SecurityPolicy::None, MessageSecurityMode::None),
        (Policy::Basic256Sha256, Mode::Sign) => {
            (SecurityPolicy::Basic256Sha256, MessageSecurityMode::Sign)
        }
        (Policy::Basic256Sha256, _) => (
            SecurityPolicy::Basic256Sha256,
            MessageSecurityMode::SignAndEncrypt,
        ),
    };
    let endpoint: EndpointDescription = (conn.endpoint.as_str(), policy.to_uri(), mode).into();
    let token = match identity {
        Identity::Anonymous => IdentityToken::Anonymous,
        Identity::User(u, p) => IdentityToken::new_user_name(u.clone(), p.clone()),
    };
    let (session, event_loop) = tokio::time::timeout(
        timeout,
        client.connect_to_matching_endpoint(endpoint, token),
    )
    .await
    .map_err(|_| format!("no answer within {} ms", conn.timeout_ms))?
    .map_err(|e| format!("{e} (is there an endpoint with {policy:?}/{mode:?}?)"))?;
    let mut driver = event_loop.spawn();
    tokio::select! {
        up = tokio::time::timeout(timeout, session.wait_for_connection()) => match up {
            Ok(true) => Ok(Open { session, driver }),
            Ok(false) => {
                driver.abort();
                Err("the session did not open".to_string())
            }
            Err(_) => {
                driver.abort();
                Err(format!("the session did not open within {} ms", conn.timeout_ms))
            }
        },
        ended = &mut driver => Err(match ended {
            Ok(status) => explain(conn, status),
            Err(e) => format!("the session's task ended: {e}"),
        }),
    }
}
