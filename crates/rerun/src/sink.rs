//! Where a recording goes: a file, a freshly spawned viewer or a running viewer.

use std::ffi::OsStr;
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::RerunError;

/// The Rerun version this crate records with; a viewer should match it.
pub const RERUN_VERSION: &str = "0.36.3";

/// Default port of a Rerun viewer's gRPC proxy.
pub const DEFAULT_VIEWER_PORT: u16 = 9876;

/// How long a `connect` probe waits for a TCP handshake before giving up.
pub const CONNECT_PROBE_TIMEOUT: Duration = Duration::from_millis(1500);

/// Destination of a recording.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Sink {
    /// Write an `.rrd` file (complete once [`crate::RunRecorder::finish`] returns).
    Save(PathBuf),
    /// Start a `rerun` viewer from PATH (or reuse one already listening on port 9876) and stream to it.
    Spawn,
    /// Stream to a running viewer, e.g. `rerun+http://127.0.0.1:9876/proxy` or `127.0.0.1:9876`.
    Connect(String),
}

/// Checks that the parent directory of an `.rrd` path exists, without creating anything.
pub(crate) fn check_save_path(path: &Path) -> Result<(), RerunError> {
    if path.as_os_str().is_empty() {
        return Err(RerunError::SaveCreate {
            path: path.to_path_buf(),
            reason: "empty file name".into(),
        });
    }
    if path.is_dir() {
        return Err(RerunError::SaveCreate {
            path: path.to_path_buf(),
            reason: "this is a directory, expected a file name such as run.rrd".into(),
        });
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(RerunError::SaveDirMissing {
            path: path.to_path_buf(),
            dir: dir.to_path_buf(),
        });
    }
    Ok(())
}

/// Turns a user address into a Rerun proxy URL plus the `host:port` to probe.
///
/// Accepts `rerun+http(s)://host[:port]/proxy`, `rerun://…`, `http://host:port` and bare `host:port`;
/// a missing port means 9876.
pub(crate) fn normalise_url(input: &str) -> Result<(String, String), RerunError> {
    let bad = |reason: &str| RerunError::BadUrl {
        url: input.to_owned(),
        reason: reason.to_owned(),
    };
    let s = input.trim();
    if s.is_empty() {
        return Err(bad("empty address"));
    }
    let (scheme, rest) = match s.split_once("://") {
        Some((sc, rest)) => match sc {
            "rerun+http" | "rerun" | "http" => ("rerun+http", rest),
            "rerun+https" | "https" => ("rerun+https", rest),
            other => return Err(bad(&format!("unknown scheme `{other}`"))),
        },
        None => ("rerun+http", s),
    };
    let (authority, path) = match rest.split_once('/') {
        Some((a, p)) => (a, p.trim_end_matches('/')),
        None => (rest, ""),
    };
    if !(path.is_empty() || path == "proxy") {
        return Err(bad(&format!(
            "path `/{path}` is not the viewer proxy endpoint `/proxy`"
        )));
    }
    if authority.is_empty() {
        return Err(bad("missing host"));
    }
    // Split off a port unless the colon belongs to a bracketed IPv6 address.
    let host_port = match authority.rsplit_once(':') {
        Some((host, port)) if !port.contains(']') => {
            let port: u16 = port
                .parse()
                .map_err(|_| bad(&format!("port `{port}` is not a number in 1..=65535")))?;
            if port == 0 {
                return Err(bad("port 0 is not a listening port"));
            }
            if host.is_empty() {
                return Err(bad("missing host"));
            }
            format!("{host}:{port}")
        }
        _ => format!("{authority}:{DEFAULT_VIEWER_PORT}"),
    };
    Ok((format!("{scheme}://{host_port}/proxy"), host_port))
}

/// Fails fast when nothing accepts a TCP connection at `host_port` within `timeout`.
pub(crate) fn probe(url: &str, host_port: &str, timeout: Duration) -> Result<(), RerunError> {
    let addrs: Vec<SocketAddr> = host_port
        .to_socket_addrs()
        .map_err(|e| RerunError::BadUrl {
            url: url.to_owned(),
            reason: format!("cannot resolve `{host_port}`: {e}"),
        })?
        .collect();
    let mut last = String::from("address resolved to nothing");
    for addr in &addrs {
        match TcpStream::connect_timeout(addr, timeout) {
            Ok(_) => return Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                last = format!("no answer within {} ms", timeout.as_millis());
            }
            Err(e) => last = e.to_string(),
        }
    }
    Err(RerunError::ConnectFailed {
        url: url.to_owned(),
        addr: host_port.to_owned(),
        reason: last,
    })
}

/// Finds an executable named `rerun` in a PATH-like list of directories.
pub(crate) fn find_viewer(path_var: Option<&OsStr>) -> Option<PathBuf> {
    let path_var = path_var?;
    std::env::split_paths(path_var)
        .map(|dir| dir.join(if cfg!(windows) { "rerun.exe" } else { "rerun" }))
        .find(|candidate| is_executable(candidate))
}

#[cfg(unix)]
fn is_executable(p: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    p.metadata()
        .map(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
        .unwrap_or(false)
}

#[cfg(not(unix))]
fn is_executable(p: &Path) -> bool {
    p.is_file()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_normalise_to_proxy_endpoint() {
        let cases = [
            ("127.0.0.1:9000", "rerun+http://127.0.0.1:9000/proxy"),
            ("localhost", "rerun+http://localhost:9876/proxy"),
            (
                "rerun+http://10.0.0.2:9876/proxy",
                "rerun+http://10.0.0.2:9876/proxy",
            ),
            ("http://h:1234/", "rerun+http://h:1234/proxy"),
            ("rerun+https://h/proxy", "rerun+https://h:9876/proxy"),
            ("[::1]:9877", "rerun+http://[::1]:9877/proxy"),
        ];
        for (input, want) in cases {
            assert_eq!(normalise_url(input).unwrap().0, want, "input {input}");
        }
    }

    #[test]
    fn bad_urls_are_rejected_with_reason() {
        for input in ["", "ftp://h:1", "h:notaport", "h:0", "h:1/catalog", ":9876"] {
            let err = normalise_url(input).unwrap_err();
            assert!(matches!(err, RerunError::BadUrl { .. }), "{input}: {err}");
        }
    }

    #[test]
    fn viewer_lookup_needs_an_executable_named_rerun() {
        let dir = std::env::temp_dir().join(format!("pneuflex-rerun-path-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path_var = std::env::join_paths([&dir]).unwrap();
        assert_eq!(find_viewer(Some(&path_var)), None);
        assert_eq!(find_viewer(None), None);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let exe = dir.join("rerun");
            std::fs::write(&exe, "#!/bin/sh\n").unwrap();
            std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o644)).unwrap();
            assert_eq!(find_viewer(Some(&path_var)), None, "not executable");
            std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o755)).unwrap();
            assert_eq!(find_viewer(Some(&path_var)), Some(exe));
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn missing_viewer_error_says_how_to_install() {
        let msg = RerunError::ViewerNotFound {
            version: RERUN_VERSION,
        }
        .to_string();
        assert!(msg.contains("pip install rerun-sdk==0.36.3"), "{msg}");
    }
}
