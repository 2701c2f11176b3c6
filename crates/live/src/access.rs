//! Who may read the live view: the bind address and the token.
//!
//! Loopback is the default and needs nothing; any other address (the shop network, a phone)
//! needs a token of at least [`MIN_TOKEN_CHARS`] characters, from the environment variable
//! [`TOKEN_ENV`] or a file, and the server refuses to start without one. When a token is set it
//! is checked on every request, whatever the address: header `Authorization: Bearer TOKEN` or
//! query `?token=TOKEN` (the page passes on the token it was opened with, since a browser's
//! `EventSource` cannot set headers). Nothing the server offers writes: no endpoint changes the
//! service.

use std::net::SocketAddr;
use std::path::Path;

/// The environment variable a token is read from.
pub const TOKEN_ENV: &str = "TRUEPOS_HTTP_TOKEN";

/// Shortest token accepted.
pub const MIN_TOKEN_CHARS: usize = 16;

/// The token from `TRUEPOS_HTTP_TOKEN`'s value (`env`) or a file (its first line, spaces
/// trimmed); the file wins when both are given. `Ok(None)`: neither. A token that is too short
/// or holds characters other than printable ASCII is refused, naming where it came from.
pub fn token_from(env: Option<String>, file: Option<&Path>) -> Result<Option<String>, String> {
    let (token, from) = match (file, env) {
        (Some(f), _) => {
            let text = truepos_files::read::read_text(f, truepos_files::CONFIG)
                .map_err(|e| format!("--http-token-file: {e}"))?;
            let first = text.lines().next().unwrap_or("").trim().to_string();
            (first, format!("--http-token-file {}", f.display()))
        }
        (None, Some(v)) => (v.trim().to_string(), TOKEN_ENV.to_string()),
        (None, None) => return Ok(None),
    };
    if token.chars().count() < MIN_TOKEN_CHARS {
        return Err(format!(
            "the live view's token from {from} has {} characters, fewer than {MIN_TOKEN_CHARS}: \
             use a long random one (e.g. `openssl rand -hex 16`)",
            token.chars().count()
        ));
    }
    if !token.chars().all(|c| c.is_ascii_graphic()) {
        return Err(format!(
            "the live view's token from {from} holds a character other than printable ASCII \
             (letters, digits, punctuation; no spaces)"
        ));
    }
    Ok(Some(token))
}

/// Refuses to serve `addr` beyond this machine without a token.
pub fn check_bind(addr: SocketAddr, token: Option<&str>) -> Result<(), String> {
    if addr.ip().is_loopback() || token.is_some() {
        return Ok(());
    }
    Err(format!(
        "--http {addr}: that address is reachable from other machines, and the live view then \
         needs a token: set {TOKEN_ENV} or give --http-token-file FILE (at least \
         {MIN_TOKEN_CHARS} characters), or serve loopback only (--http 127.0.0.1:PORT)"
    ))
}

/// Whether a request carries the token: its `Authorization: Bearer` header or its `token`
/// query parameter. Compared in time independent of where the first difference is.
pub fn allowed(
    token: Option<&str>,
    authorization: Option<&str>,
    query_token: Option<&str>,
) -> bool {
    let Some(token) = token else {
        return true;
    };
    let bearer = authorization
        .and_then(|h| h.trim().strip_prefix("Bearer "))
        .map(str::trim);
    [bearer, query_token]
        .into_iter()
        .flatten()
        .any(|given| same(given.as_bytes(), token.as_bytes()))
}

fn same(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The value of query parameter `name` in a request target (`/path?a=1&b=2`), percent-decoded.
pub fn query_param(target: &str, name: &str) -> Option<String> {
    let query = target.split_once('?')?.1;
    query.split('&').find_map(|pair| {
        let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
        (k == name).then(|| percent_decode(v))
    })
}

fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'%' if i + 2 < b.len() => {
                let hex = std::str::from_utf8(&b[i + 1..i + 3]).ok();
                match hex.and_then(|h| u8::from_str_radix(h, 16).ok()) {
                    Some(v) => {
                        out.push(v);
                        i += 3;
                        continue;
                    }
                    None => out.push(b'%'),
                }
            }
            b'+' => out.push(b' '),
            c => out.push(c),
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beyond_loopback_a_token_is_required() {
        let lan: SocketAddr = "0.0.0.0:8080".parse().unwrap();
        let local: SocketAddr = "127.0.0.1:8080".parse().unwrap();
        let v6: SocketAddr = "[::1]:8080".parse().unwrap();
        assert!(check_bind(local, None).is_ok());
        assert!(check_bind(v6, None).is_ok());
        let e = check_bind(lan, None).unwrap_err();
        assert!(
            e.contains(TOKEN_ENV) && e.contains("--http-token-file"),
            "{e}"
        );
        assert!(check_bind(lan, Some("0123456789abcdef")).is_ok());
    }

    #[test]
    fn tokens_are_long_and_printable() {
        assert_eq!(token_from(None, None), Ok(None));
        assert!(token_from(Some("short".into()), None)
            .unwrap_err()
            .contains("fewer than 16"));
        assert!(token_from(Some("with a space in it!".into()), None).is_err());
        assert_eq!(
            token_from(Some(" 0123456789abcdef\n".into()), None),
            Ok(Some("0123456789abcdef".into()))
        );
    }

    #[test]
    fn every_request_needs_the_token_by_header_or_query() {
        let t = Some("0123456789abcdef");
        assert!(allowed(None, None, None));
        assert!(!allowed(t, None, None));
        assert!(!allowed(t, Some("Bearer 0123456789abcdeX"), None));
        assert!(!allowed(t, Some("Basic 0123456789abcdef"), None));
        assert!(!allowed(t, None, Some("0123456789abcde")));
        assert!(allowed(t, Some("Bearer 0123456789abcdef"), None));
        assert!(allowed(t, None, Some("0123456789abcdef")));
        assert_eq!(
            query_param("/api/history?window_s=900&token=a%2Bb+c", "token"),
            Some("a+b c".into())
        );
        assert_eq!(query_param("/x?a=1", "token"), None);
        assert_eq!(query_param("/x?token=%zz%4", "token"), Some("%zz%4".into()));
    }
}
