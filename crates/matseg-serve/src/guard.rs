//! Who may talk to the server. A server on 127.0.0.1 is reachable by every
//! web page open in the user's browser, so, as local web apps of this kind
//! do, it answers only requests that are its own:
//!
//! - the `Host` header names an address the server answers to (loopback
//!   names, `--host`, `--allowed-host`), so a page on another domain that
//!   rebinds its name to 127.0.0.1 is refused; a request with two `Host`
//!   headers, or whose request line names a host itself (the absolute
//!   form `GET http://HOST/...`, which takes precedence over `Host`), is
//!   refused too;
//! - an `Origin` header, when a browser sends one, is the server's own,
//!   and API calls a browser marks as coming from another site
//!   (`Sec-Fetch-Site`) are refused, so another page can neither send nor
//!   read them;
//! - a POST carries a body type a plain cross-site form cannot send
//!   (`application/json`, or the file's type for uploads), so a browser
//!   must ask first (a CORS preflight, which the server never grants);
//! - API calls carry the server's token (per run, unless turned off),
//!   as the `x-matseg-token` header or the `token` query parameter.
//!
//! Every answer also tells the browser not to frame the pages, not to
//! guess content types and not to pass the address (and its token) on.

use crate::app::ApiError;
use axum::extract::{Request, State};
use axum::http::{header, HeaderMap, HeaderValue, Method, StatusCode, Uri};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use std::net::IpAddr;
use std::sync::Arc;

/// Which token API calls must carry.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum TokenChoice {
    /// A random token made when the server starts (the default).
    #[default]
    PerRun,
    /// This token.
    Given(String),
    /// None: any request from this machine's own pages is answered
    /// (loopback addresses only).
    Off,
}

/// What the guard lets in.
#[derive(Clone, Debug)]
pub struct Access {
    /// The token API calls must carry, when there is one.
    pub token: Option<String>,
    /// Host names and addresses the server answers to (lower case, no
    /// port, IPv6 without brackets).
    hosts: Vec<String>,
    /// Whether any IP address is a name the server answers to (it is bound
    /// to all of them: an address cannot be rebound, only a name can).
    any_address: bool,
}

impl Access {
    /// The names a server bound to `host` answers to: this machine's
    /// loopback names, `host` itself and `allowed`; with `token`.
    pub fn new(host: &str, allowed: &[String], token: Option<String>) -> Self {
        let mut hosts: Vec<String> = ["localhost", "127.0.0.1", "::1"]
            .into_iter()
            .map(String::from)
            .collect();
        hosts.extend(
            std::iter::once(host)
                .chain(allowed.iter().map(String::as_str))
                .map(normalise_host),
        );
        let any_address = normalise_host(host)
            .parse::<IpAddr>()
            .is_ok_and(|ip| ip.is_unspecified());
        Self {
            token,
            hosts,
            any_address,
        }
    }

    /// Whether the `Host` header value `host` (a name or address, maybe
    /// with a port) is one this server answers to.
    pub fn allows_host(&self, host: &str) -> bool {
        let name = normalise_host(strip_port(host));
        self.hosts.contains(&name) || (self.any_address && name.parse::<IpAddr>().is_ok())
    }

    /// Why `request` is refused, if it is.
    fn refusal(&self, method: &Method, uri: &Uri, headers: &HeaderMap) -> Option<ApiError> {
        let (path, query) = (uri.path(), uri.query());
        let forbidden = |message: String| ApiError::new(StatusCode::FORBIDDEN, message);
        let text = |name: header::HeaderName| headers.get(name).map(|v| v.to_str().unwrap_or("?"));
        if uri.scheme().is_some() || uri.authority().is_some() {
            return Some(ApiError::bad(format!(
                "request target {:?}: give the path alone (/api/...), with the server's address in Host",
                uri.to_string()
            )));
        }
        if headers.get_all(header::HOST).iter().nth(1).is_some() {
            return Some(ApiError::bad(
                "a request with two Host headers: give one, the server's address",
            ));
        }
        let Some(host) = text(header::HOST) else {
            return Some(ApiError::bad("a request without a Host header"));
        };
        if !self.allows_host(host) {
            return Some(forbidden(format!(
                "Host {host:?}: not an address this server answers to (start it with --allowed-host NAME to allow one)"
            )));
        }
        if let Some(origin) = text(header::ORIGIN) {
            if !origin.eq_ignore_ascii_case(&format!("http://{host}")) {
                return Some(forbidden(format!(
                    "Origin {origin:?}: requests from other web pages are refused"
                )));
            }
        }
        if !path.starts_with("/api/") {
            return None;
        }
        if let Some(site) = text(header::HeaderName::from_static("sec-fetch-site")) {
            if !matches!(site, "same-origin" | "none") {
                return Some(forbidden(format!(
                    "Sec-Fetch-Site {site:?}: requests from other web pages are refused"
                )));
            }
        }
        if let Some(token) = &self.token {
            let from_header = headers.get("x-matseg-token").and_then(|v| v.to_str().ok());
            let from_query =
                query.and_then(|q| q.split('&').find_map(|kv| kv.strip_prefix("token=")));
            let valid = |given: Option<&str>| given.is_some_and(|g| same_secret(g, token));
            if !valid(from_header) && !valid(from_query) {
                return Some(ApiError::new(
                    StatusCode::UNAUTHORIZED,
                    "a valid token is required: open the address `matseg serve` printed (it ends in ?token=...)",
                ));
            }
        }
        if *method == Method::POST {
            let kind = text(header::CONTENT_TYPE).unwrap_or_default();
            if !is_typed_body(kind) {
                return Some(ApiError::new(
                    StatusCode::UNSUPPORTED_MEDIA_TYPE,
                    format!(
                        "Content-Type {kind:?}: a POST needs application/json (uploads: the file's image or video type, or application/octet-stream)"
                    ),
                ));
            }
        }
        None
    }
}

/// A `Host` value without its port (`[::1]:8080` -> `[::1]`).
fn strip_port(host: &str) -> &str {
    if host.starts_with('[') {
        return host.find(']').map_or(host, |end| &host[..=end]);
    }
    match host.rsplit_once(':') {
        Some((name, port)) if !name.contains(':') && port.bytes().all(|b| b.is_ascii_digit()) => {
            name
        }
        _ => host,
    }
}

/// A host name compared as browsers resolve it: lower case, without the
/// root's trailing dot, IPv6 without brackets.
fn normalise_host(host: &str) -> String {
    host.trim_start_matches('[')
        .trim_end_matches(']')
        .trim_end_matches('.')
        .to_ascii_lowercase()
}

/// Whether a POST's `Content-Type` is one no cross-site form can send:
/// JSON, or an upload's file type.
fn is_typed_body(kind: &str) -> bool {
    let essence = kind
        .split(';')
        .next()
        .unwrap_or_default()
        .trim()
        .to_ascii_lowercase();
    essence == "application/json"
        || essence == "application/octet-stream"
        || essence
            .strip_prefix("image/")
            .is_some_and(|s| !s.is_empty())
        || essence
            .strip_prefix("video/")
            .is_some_and(|s| !s.is_empty())
}

/// Whether `given` is `token`, compared in time independent of where they
/// differ.
fn same_secret(given: &str, token: &str) -> bool {
    given.len() == token.len()
        && given
            .bytes()
            .zip(token.bytes())
            .fold(0u8, |diff, (a, b)| diff | (a ^ b))
            == 0
}

/// The fewest characters a chosen token (`--token`) may have.
pub const MIN_TOKEN_CHARS: usize = 8;

/// Why `token` cannot be the server's token, if it cannot: it must have
/// [`MIN_TOKEN_CHARS`] characters or more, each URL-safe (`A-Z a-z 0-9 .
/// _ ~ -`), so that it goes into the printed address and a header as it
/// is and is not guessed at once.
pub fn check_token(token: &str) -> Result<(), TokenError> {
    if let Some(c) = token
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '~' | '-')))
    {
        return Err(TokenError::NotUrlSafe(c));
    }
    let chars = token.chars().count();
    if chars < MIN_TOKEN_CHARS {
        return Err(TokenError::TooShort(chars));
    }
    Ok(())
}

/// Why a chosen token cannot be used.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub enum TokenError {
    /// A character that does not go into an address as it is.
    #[error("--token: {0:?} is not a URL-safe character; use only {SAFE_CHARACTERS}")]
    NotUrlSafe(char),
    /// Fewer characters than [`MIN_TOKEN_CHARS`].
    #[error(
        "--token: too short ({0} of at least {MIN_TOKEN_CHARS} characters from {SAFE_CHARACTERS})"
    )]
    TooShort(usize),
}

/// The characters a chosen token may hold, as the errors list them.
const SAFE_CHARACTERS: &str = "A-Z a-z 0-9 . _ ~ -";

/// A new per-run token: 128 random bits as 32 hex digits.
pub fn new_token() -> Result<String, getrandom::Error> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes)?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// The middleware: refuses what [`Access`] refuses, and adds the headers
/// that keep the pages out of other pages' frames and their address out of
/// `Referer`.
pub async fn check(State(access): State<Arc<Access>>, request: Request, next: Next) -> Response {
    let refused = access.refusal(request.method(), request.uri(), request.headers());
    let mut response = match refused {
        Some(error) => error.into_response(),
        None => next.run(request).await,
    };
    let headers = response.headers_mut();
    for (name, value) in [
        ("x-content-type-options", "nosniff"),
        ("x-frame-options", "DENY"),
        ("content-security-policy", "frame-ancestors 'none'"),
        ("referrer-policy", "no-referrer"),
    ] {
        headers.insert(name, HeaderValue::from_static(value));
    }
    response
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(pairs: &[(&'static str, &str)]) -> HeaderMap {
        let mut map = HeaderMap::new();
        for (name, value) in pairs {
            map.insert(*name, HeaderValue::from_str(value).unwrap());
        }
        map
    }

    fn status(
        access: &Access,
        method: Method,
        path: &str,
        pairs: &[(&'static str, &str)],
    ) -> StatusCode {
        let uri: Uri = path.parse().unwrap();
        access
            .refusal(&method, &uri, &headers(pairs))
            .map_or(StatusCode::OK, |e| e.status())
    }

    #[test]
    fn hosts_are_compared_without_port_case_or_trailing_dot() {
        let access = Access::new("127.0.0.1", &["Box.Lan".into()], None);
        for host in [
            "localhost:8080",
            "LOCALHOST",
            "localhost.",
            "127.0.0.1:1",
            "[::1]:8080",
            "box.lan:80",
        ] {
            assert!(access.allows_host(host), "{host}");
        }
        for host in [
            "evil.example",
            "localhost.evil.example",
            "127.0.0.2",
            "[::2]:80",
            "evil.example:127.0.0.1",
        ] {
            assert!(!access.allows_host(host), "{host}");
        }
        let everywhere = Access::new("0.0.0.0", &[], Some("t".into()));
        assert!(everywhere.allows_host("192.168.1.20:8080"));
        assert!(everywhere.allows_host("[fe80::1]:8080"));
        assert!(!everywhere.allows_host("evil.example:8080"));
    }

    #[test]
    fn forged_requests_are_refused_and_the_pages_own_are_not() {
        let access = Access::new("127.0.0.1", &[], Some("s3cret".into()));
        let own = [("host", "127.0.0.1:8080"), ("x-matseg-token", "s3cret")];
        let json = ("content-type", "application/json");
        assert_eq!(
            status(&access, Method::GET, "/api/photos", &own),
            StatusCode::OK
        );
        assert_eq!(
            status(
                &access,
                Method::POST,
                "/api/annotation",
                &[own[0], own[1], json, ("origin", "http://127.0.0.1:8080")]
            ),
            StatusCode::OK
        );
        assert_eq!(
            status(
                &access,
                Method::GET,
                "/api/photos?a=1&token=s3cret",
                &own[..1]
            ),
            StatusCode::OK
        );
        // A rebinding page: its own name in Host.
        assert_eq!(
            status(
                &access,
                Method::GET,
                "/api/photos",
                &[("host", "evil.example"), own[1]]
            ),
            StatusCode::FORBIDDEN
        );
        assert_eq!(
            status(&access, Method::GET, "/", &[("host", "evil.example:8080")]),
            StatusCode::FORBIDDEN
        );
        // Another page's fetch: its origin, or the browser's cross-site mark.
        for origin in [
            "http://evil.example",
            "null",
            "http://127.0.0.1:9999",
            "https://127.0.0.1:8080",
        ] {
            assert_eq!(
                status(
                    &access,
                    Method::POST,
                    "/api/annotation",
                    &[own[0], own[1], json, ("origin", origin)]
                ),
                StatusCode::FORBIDDEN,
                "{origin}"
            );
        }
        assert_eq!(
            status(
                &access,
                Method::GET,
                "/api/photo",
                &[own[0], own[1], ("sec-fetch-site", "cross-site")]
            ),
            StatusCode::FORBIDDEN
        );
        assert_eq!(
            status(
                &access,
                Method::GET,
                "/api/photo",
                &[own[0], own[1], ("sec-fetch-site", "same-site")]
            ),
            StatusCode::FORBIDDEN
        );
        // A page opened from a link elsewhere is still served (it holds no data).
        assert_eq!(
            status(
                &access,
                Method::GET,
                "/",
                &[own[0], ("sec-fetch-site", "cross-site")]
            ),
            StatusCode::OK
        );
        // A plain form's body types, or none.
        for kind in [
            "text/plain",
            "application/x-www-form-urlencoded",
            "multipart/form-data; boundary=x",
            "",
        ] {
            let mut pairs = vec![own[0], own[1]];
            if !kind.is_empty() {
                pairs.push(("content-type", kind));
            }
            assert_eq!(
                status(&access, Method::POST, "/api/annotation", &pairs),
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "{kind}"
            );
        }
        for kind in [
            "application/json; charset=utf-8",
            "image/jpeg",
            "video/x-matroska",
            "application/octet-stream",
        ] {
            assert_eq!(
                status(
                    &access,
                    Method::POST,
                    "/api/upload",
                    &[own[0], own[1], ("content-type", kind)]
                ),
                StatusCode::OK,
                "{kind}"
            );
        }
        // Tokens: none, another, a prefix.
        for token in [None, Some("s3cre"), Some("s3cret2"), Some("S3CRET")] {
            let mut pairs = vec![own[0]];
            if let Some(t) = token {
                pairs.push(("x-matseg-token", t));
            }
            assert_eq!(
                status(&access, Method::GET, "/api/photos", &pairs),
                StatusCode::UNAUTHORIZED,
                "{token:?}"
            );
        }
        assert_eq!(
            status(&access, Method::GET, "/api/photos", &[]),
            StatusCode::BAD_REQUEST
        );
    }

    #[test]
    fn a_second_host_or_a_host_in_the_request_line_is_refused() {
        let access = Access::new("127.0.0.1", &[], None);
        let own = [("host", "127.0.0.1:8080")];
        assert_eq!(
            status(&access, Method::GET, "/api/photos", &own),
            StatusCode::OK
        );
        for target in [
            "http://evil.example/api/photos",
            "http://127.0.0.1:8080/api/photos",
            "evil.example:80",
        ] {
            assert_eq!(
                status(&access, Method::GET, target, &own),
                StatusCode::BAD_REQUEST,
                "{target}"
            );
        }
        for second in ["evil.example", "127.0.0.1:8080"] {
            let mut two = headers(&own);
            two.append("host", HeaderValue::from_static(second));
            let uri: Uri = "/api/photos".parse().unwrap();
            let refused = access.refusal(&Method::GET, &uri, &two).unwrap();
            assert_eq!(refused.status(), StatusCode::BAD_REQUEST, "{second}");
        }
    }

    #[test]
    fn chosen_tokens_are_long_enough_and_url_safe() {
        for good in ["test-token", "abcdefgh", "A.b_c~d-12345678"] {
            assert_eq!(check_token(good), Ok(()), "{good}");
        }
        for (bad, said) in [
            ("", "too short (0 of at least 8 characters"),
            ("a", "too short (1 of at least 8 characters"),
            ("abcdefg", "too short (7 of"),
            (" ", "' ' is not a URL-safe character"),
            ("abcdefgh ", "' ' is not a URL-safe character"),
            ("abcd&efgh", "'&' is not a URL-safe character"),
            ("abcdéfgh", "'é' is not a URL-safe character"),
        ] {
            let message = check_token(bad).unwrap_err().to_string();
            assert!(message.starts_with("--token: "), "{message}");
            assert!(message.contains(said), "{bad:?}: {message}");
            assert!(!message.contains('\n'));
        }
    }

    #[test]
    fn per_run_tokens_are_new_each_time() {
        let (a, b) = (new_token().unwrap(), new_token().unwrap());
        assert_eq!(a.len(), 32);
        assert!(a.bytes().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
        assert!(same_secret(&a, &a.clone()));
        assert!(!same_secret(&a, &b));
    }
}
