//! Requests to end a coordinator's run early, from outside the process.
//!
//! Two channels feed one [`StopRequest`]:
//! - **stdin lines** `{"type":"stop","reason":"pilotExited"}` ([`Control`]): `sadesim run
//!   --processes` sends one when the pilot exits.
//! - **an annotations file** (`--control-file`): on Kubernetes the operator sets the
//!   annotation [`STOP_ANNOTATION`] on the coordinator Pod, and a downward-API volume
//!   projects the Pod's annotations into a file the coordinator polls. Kubernetes RBAC
//!   decides who may stop a run (whoever may patch the Pod), nothing listens on the network,
//!   and the operator's server-side apply of the Pod stays idempotent (the same annotation
//!   every reconcile). The kubelet refreshes the file when the Pod changes, in seconds.
//!
//! The coordinator ends the run after the current window with the request's reason as
//! `endReason` (`summary.json`, the `runEnded` event), exactly as for the stdin line.

use std::io::{BufRead, IsTerminal};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

pub use sadesim_crds::outcome::control::{Control, STOP_ANNOTATION};
use sadesim_crds::outcome::ending::EndReason;

/// How often the annotations file is read. The kubelet's own refresh takes longer.
pub const POLL_PERIOD: Duration = Duration::from_millis(250);

/// The pending request to end the run, shared by the channels that fill it and the run
/// loop that takes it. The first request wins; later ones are ignored.
#[derive(Clone, Debug, Default)]
pub struct StopRequest(Arc<Mutex<Slot>>);

#[derive(Debug, Default)]
struct Slot {
    reason: Option<EndReason>,
    /// A request arrived once (taken or not): later ones change nothing.
    requested: bool,
}

impl StopRequest {
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks to end the run with `reason`, unless a request came first.
    pub fn request(&self, reason: impl Into<EndReason>) {
        if let Ok(mut slot) = self.0.lock()
            && !slot.requested
        {
            slot.requested = true;
            slot.reason = Some(reason.into());
        }
    }

    /// The request, once: the run loop ends the run with it.
    pub fn take(&self) -> Option<EndReason> {
        self.0.lock().ok()?.reason.take()
    }

    /// Reads [`Control`] lines from stdin on a thread, unless stdin is a terminal (a
    /// coordinator started by hand in the background must not read it). Other lines are
    /// ignored.
    pub fn read_stdin(&self) {
        if std::io::stdin().is_terminal() {
            return;
        }
        let requests = self.clone();
        std::thread::spawn(move || {
            for line in std::io::stdin().lock().lines().map_while(Result::ok) {
                if let Ok(Control::Stop { reason }) = serde_json::from_str(&line) {
                    requests.request(reason);
                }
            }
        });
    }

    /// Polls `path`, a downward-API file of the Pod's annotations, every [`POLL_PERIOD`] on a
    /// thread, until [`STOP_ANNOTATION`] appears with a valid reason.
    ///
    /// # Errors
    /// `path` cannot be read now: the flag is wrong (the kubelet writes the file before the
    /// container starts), and a coordinator that could never be stopped must not start.
    pub fn watch_annotations(&self, path: &Path) -> std::io::Result<()> {
        std::fs::read_to_string(path)
            .map_err(|e| std::io::Error::new(e.kind(), format!("--control-file {}: {e}", path.display())))?;
        let requests = self.clone();
        let path: PathBuf = path.to_path_buf();
        std::thread::spawn(move || {
            let mut refused = None;
            loop {
                // Unreadable for a moment (the kubelet swaps the file atomically, but a
                // hand-written one may be mid-write): try again at the next poll.
                if let Ok(text) = std::fs::read_to_string(&path) {
                    match stop_reason(&text) {
                        Some(Ok(reason)) => {
                            eprintln!("coordinator: {STOP_ANNOTATION}={reason:?}: ending the run after this window");
                            requests.request(reason);
                            return;
                        }
                        Some(Err(message)) if refused.as_ref() != Some(&message) => {
                            eprintln!("coordinator: {message}");
                            refused = Some(message);
                        }
                        _ => {}
                    }
                }
                std::thread::sleep(POLL_PERIOD);
            }
        });
        Ok(())
    }
}

/// The value of [`STOP_ANNOTATION`] in a downward-API annotations file: `None` when absent,
/// `Err` (saying why) when it is not a reason.
///
/// The kubelet writes one `key="value"` line per annotation, sorted, the value quoted as
/// Go's `%q` does. A reason is 1 to 64 ASCII letters, digits or `-_.:` (it becomes
/// `endReason` in `summary.json`).
pub fn stop_reason(annotations: &str) -> Option<Result<EndReason, String>> {
    let prefix = format!("{STOP_ANNOTATION}=");
    let quoted = annotations.lines().find_map(|line| line.strip_prefix(&prefix))?;
    let refuse = |why: &str| Err(format!("annotation {STOP_ANNOTATION}={quoted}: {why}; the run goes on"));
    let Some(value) = unquote(quoted) else {
        return Some(refuse("expected a double-quoted string"));
    };
    let valid = !value.is_empty()
        && value.len() <= 64
        && value.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | ':'));
    Some(if valid {
        Ok(EndReason::from(value.as_str()))
    } else {
        refuse("expected 1 to 64 ASCII letters, digits or -_.:")
    })
}

/// A Go `%q` string: `"..."` with `\"`, `\\`, `\n`, `\t` and `\r` escapes (a reason needs
/// no others; anything else is refused by the caller's check).
fn unquote(quoted: &str) -> Option<String> {
    let inner = quoted.strip_prefix('"')?.strip_suffix('"')?;
    let mut out = String::with_capacity(inner.len());
    let mut chars = inner.chars();
    while let Some(c) = chars.next() {
        out.push(match c {
            '\\' => match chars.next()? {
                'n' => '\n',
                't' => '\t',
                'r' => '\r',
                other => other,
            },
            '"' => return None,
            c => c,
        });
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::record::test_dir::TempDir;

    /// What the kubelet writes for a coordinator Pod the operator asked to stop.
    const ANNOTATIONS: &str = "kubernetes.io/config.seen=\"2026-12-02T10:00:00Z\"\n\
                               sadesim.io/stop=\"pilotExited\"\n\
                               team=\"a \\\"quoted\\\" value\"";

    #[test]
    fn the_stop_annotation_is_read_among_the_others() {
        assert_eq!(stop_reason(ANNOTATIONS), Some(Ok(EndReason::PilotExited)));
        assert_eq!(stop_reason("team=\"drones\"\nkubernetes.io/config.source=\"api\""), None);
        assert_eq!(stop_reason(""), None);
        // A reason of the requester's own is kept as given.
        assert_eq!(
            stop_reason("sadesim.io/stop=\"operatorSaidSo\""),
            Some(Ok(EndReason::Requested("operatorSaidSo".into())))
        );
        // Another annotation whose name ends the same way is not ours.
        assert_eq!(stop_reason("example.com/sadesim.io/stop=\"x\""), None);
    }

    #[test]
    fn a_malformed_or_odd_reason_is_refused_with_the_line() {
        let unquoted = stop_reason("sadesim.io/stop=pilotExited").unwrap().unwrap_err();
        assert_eq!(
            unquoted,
            "annotation sadesim.io/stop=pilotExited: expected a double-quoted string; the run goes on"
        );
        let spaced = stop_reason("sadesim.io/stop=\"pilot exited\"").unwrap().unwrap_err();
        assert!(spaced.contains("expected 1 to 64 ASCII letters, digits or -_.:"), "{spaced}");
        assert!(stop_reason("sadesim.io/stop=\"\"").unwrap().is_err());
        assert!(stop_reason(&format!("sadesim.io/stop=\"{}\"", "a".repeat(65))).unwrap().is_err());
        assert_eq!(unquote(r#""a\"b\\c""#).as_deref(), Some(r#"a"b\c"#));
        assert_eq!(unquote(r#""a"b""#), None);
    }

    #[test]
    fn the_first_request_wins_and_is_taken_once() {
        let stop = StopRequest::new();
        assert_eq!(stop.take(), None);
        stop.request(EndReason::PilotExited);
        stop.request(EndReason::Aborted);
        assert_eq!(stop.take(), Some(EndReason::PilotExited));
        assert_eq!(stop.take(), None);
        stop.request("again");
        assert_eq!(stop.take(), None, "a request after the first changes nothing");
    }

    #[test]
    fn the_watcher_sees_the_annotation_appear() {
        let dir = TempDir::new("control-file");
        let file = dir.0.join("annotations");
        std::fs::write(&file, "kubernetes.io/config.source=\"api\"\n").unwrap();
        let stop = StopRequest::new();
        stop.watch_annotations(&file).unwrap();
        std::thread::sleep(POLL_PERIOD * 2);
        assert_eq!(stop.take(), None, "no stop annotation yet");
        std::fs::write(&file, ANNOTATIONS).unwrap();
        let mut reason = None;
        for _ in 0..40 {
            reason = stop.take();
            if reason.is_some() {
                break;
            }
            std::thread::sleep(POLL_PERIOD / 2);
        }
        assert_eq!(reason, Some(EndReason::PilotExited));
    }

    #[test]
    fn a_missing_control_file_is_an_error_naming_the_flag() {
        let error = StopRequest::new().watch_annotations(Path::new("/nonexistent/annotations")).unwrap_err();
        assert!(error.to_string().starts_with("--control-file /nonexistent/annotations: "), "{error}");
    }
}
