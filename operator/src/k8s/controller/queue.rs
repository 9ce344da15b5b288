//! Admission without Kueue (pure): a run stays `Queued` until its whole gang fits what the
//! namespace's ResourceQuotas leave free, no earlier run of the namespace is still waiting
//! (FIFO by creationTimestamp, then name), and the namespace runs fewer than
//! `maxConcurrentRuns` (0 = unlimited).
//!
//! # Caveats
//! Quota `used` counts pods that exist. A run admitted a moment ago whose shards do not
//! exist yet (phase `GeneratingAssets`) is counted as reserved with its whole gang; between
//! the status write of an admission and the next list of runs, a second run may still
//! see the old picture (the API server's quota admission then refuses the excess pods,
//! and the Jobs retry).

use k8s_openapi::api::core::v1::ResourceQuota;
use k8s_openapi::jiff::Timestamp;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::status::Phase;

/// What a run needs at once: every pod of the gang (shards, coordinator, routers,
/// renderer, pilot).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Gang {
    /// CPU requests, millicores.
    pub cpu_millis: u64,
    /// Memory requests, bytes.
    pub memory_bytes: u64,
    /// Pods.
    pub pods: u64,
}

impl Gang {
    /// The gang of a planned run (requests as `sadesim plan` shows them).
    pub fn of(plan: &RunPlan) -> Self {
        let total = plan.resources.total(plan.segments.len());
        let pods = plan.shards.len()
            + 1
            + plan.segments.len()
            + usize::from(plan.resources.renderer.is_some())
            + usize::from(plan.resources.pilot.is_some());
        Self {
            cpu_millis: u64::from(total.cpu_millis),
            memory_bytes: u64::from(total.memory_mib) * 1024 * 1024,
            pods: pods as u64,
        }
    }

    fn plus(self, o: Gang) -> Gang {
        Gang {
            cpu_millis: self.cpu_millis + o.cpu_millis,
            memory_bytes: self.memory_bytes + o.memory_bytes,
            pods: self.pods + o.pods,
        }
    }
}

/// Another run of the namespace, as the queue sees it.
#[derive(Clone, Debug, PartialEq)]
pub struct QueuedRun {
    pub name: String,
    pub created: Option<Timestamp>,
    pub phase: Phase,
    /// Admitted by Kueue instead (spec.queue with Kueue on): not in our FIFO.
    pub kueue: bool,
    /// Its gang, when it plans (used for runs admitted whose pods do not exist yet).
    pub gang: Option<Gang>,
}

impl QueuedRun {
    /// Holds (or is about to hold) cluster resources.
    fn active(&self) -> bool {
        matches!(self.phase, Phase::GeneratingAssets | Phase::Starting | Phase::Running | Phase::Archiving)
    }
}

/// What the namespace offers.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QueueView {
    /// Every run of the namespace (including the one being admitted, which is skipped).
    pub runs: Vec<QueuedRun>,
    pub quotas: Vec<ResourceQuota>,
    /// Active runs allowed per namespace; 0 = unlimited.
    pub max_concurrent_runs: u32,
}

/// The queue's answer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Admission {
    Admitted,
    /// Stay `Queued`: `reason` is the Scheduled condition's reason, `message` says why.
    Waiting {
        reason: &'static str,
        message: String,
    },
}

/// Decides whether `name` (created at `created`, needing `gang`) may start now.
pub fn admit(name: &str, created: Option<Timestamp>, gang: Gang, view: &QueueView) -> Admission {
    let key = |created: Option<Timestamp>, name: &str| (created.map(|t| t.as_nanosecond()), name.to_string());
    let me = key(created, name);
    let others = view.runs.iter().filter(|r| r.name != name);
    let ahead = others
        .clone()
        .filter(|r| !r.kueue && matches!(r.phase, Phase::Pending | Phase::Queued))
        .filter(|r| key(r.created, &r.name) < me)
        .count();
    if ahead > 0 {
        let runs = if ahead == 1 { "run" } else { "runs" };
        return Admission::Waiting {
            reason: "WaitingForEarlierRuns",
            message: format!("{ahead} earlier {runs} of this namespace queued first (FIFO)"),
        };
    }
    let active = others.clone().filter(|r| r.active()).count();
    if view.max_concurrent_runs > 0 && active >= view.max_concurrent_runs as usize {
        return Admission::Waiting {
            reason: "MaxConcurrentRuns",
            message: format!(
                "{active} runs active in this namespace; the operator allows {} (--max-concurrent-runs)",
                view.max_concurrent_runs
            ),
        };
    }
    // Admitted runs whose gang is not created yet: their pods are not in `used`.
    let reserved =
        others.filter(|r| r.phase == Phase::GeneratingAssets).filter_map(|r| r.gang).fold(Gang::default(), Gang::plus);
    for quota in &view.quotas {
        if let Some(message) = shortfall(quota, gang, reserved) {
            return Admission::Waiting { reason: "QuotaExceeded", message };
        }
    }
    Admission::Admitted
}

/// Why `gang` does not fit `quota` (hard - used - reserved), or `None` when it fits.
fn shortfall(quota: &ResourceQuota, gang: Gang, reserved: Gang) -> Option<String> {
    let hard = quota
        .status
        .as_ref()
        .and_then(|s| s.hard.as_ref())
        .or_else(|| quota.spec.as_ref().and_then(|s| s.hard.as_ref()))?;
    let used = quota.status.as_ref().and_then(|s| s.used.as_ref());
    let name = quota.metadata.name.as_deref().unwrap_or("(unnamed)");
    for (resource, limit) in hard {
        let (need, have_reserved, unit) = match resource.as_str() {
            "cpu" | "requests.cpu" | "limits.cpu" => (gang.cpu_millis as f64, reserved.cpu_millis as f64, 1000.0),
            "memory" | "requests.memory" | "limits.memory" => {
                (gang.memory_bytes as f64, reserved.memory_bytes as f64, 1.0)
            }
            "pods" | "count/pods" => (gang.pods as f64, reserved.pods as f64, 1.0),
            _ => continue,
        };
        let Some(limit) = parse_quantity(&limit.0) else { continue };
        let in_use = used.and_then(|u| u.get(resource)).and_then(|q| parse_quantity(&q.0)).unwrap_or(0.0);
        let free = (limit - in_use) * unit - have_reserved;
        if need > free + 1e-9 {
            let show = |v: f64| {
                if unit == 1000.0 { format!("{:.0}m", v) } else { format!("{v:.0}") }
            };
            return Some(format!(
                "ResourceQuota {name}: the run needs {} of {resource} at once, {} free",
                show(need),
                show(free.max(0.0))
            ));
        }
    }
    None
}

/// A Kubernetes quantity (`500m`, `2`, `1.5Gi`, `1e3`, `128974848`) in base units (cores,
/// bytes, count). `None` when it is not a quantity.
pub fn parse_quantity(s: &str) -> Option<f64> {
    let s = s.trim();
    let split = s.find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '+' || c == '-')).unwrap_or(s.len());
    let (number, suffix) = s.split_at(split);
    let value: f64 = number.parse().ok()?;
    let factor = match suffix {
        "" => 1.0,
        "n" => 1e-9,
        "u" => 1e-6,
        "m" => 1e-3,
        "k" => 1e3,
        "M" => 1e6,
        "G" => 1e9,
        "T" => 1e12,
        "P" => 1e15,
        "E" => 1e18,
        "Ki" => 1024.0,
        "Mi" => 1024f64.powi(2),
        "Gi" => 1024f64.powi(3),
        "Ti" => 1024f64.powi(4),
        "Pi" => 1024f64.powi(5),
        "Ei" => 1024f64.powi(6),
        e if e.starts_with(['e', 'E']) => 10f64.powi(e[1..].parse::<i32>().ok()?),
        _ => return None,
    };
    Some(value * factor)
}

#[cfg(test)]
mod tests {
    use super::*;
    use k8s_openapi::api::core::v1::ResourceQuotaStatus;
    use k8s_openapi::apimachinery::pkg::api::resource::Quantity;

    fn quota(hard: &[(&str, &str)], used: &[(&str, &str)]) -> ResourceQuota {
        let map = |kv: &[(&str, &str)]| kv.iter().map(|(k, v)| (k.to_string(), Quantity(v.to_string()))).collect();
        let mut q = ResourceQuota::default();
        q.metadata.name = Some("team".into());
        q.status = Some(ResourceQuotaStatus { hard: Some(map(hard)), used: Some(map(used)) });
        q
    }

    fn at(s: i64) -> Option<Timestamp> {
        Some(Timestamp::from_second(1_800_000_000 + s).unwrap())
    }

    fn run(name: &str, created: i64, phase: Phase) -> QueuedRun {
        QueuedRun { name: name.into(), created: at(created), phase, kueue: false, gang: None }
    }

    const GANG: Gang = Gang { cpu_millis: 2000, memory_bytes: 1 << 30, pods: 4 };

    #[test]
    fn quantities() {
        assert_eq!(parse_quantity("500m"), Some(0.5));
        assert_eq!(parse_quantity("2"), Some(2.0));
        assert_eq!(parse_quantity("1Gi"), Some(1073741824.0));
        assert_eq!(parse_quantity("1.5k"), Some(1500.0));
        assert_eq!(parse_quantity("1e3"), Some(1000.0));
        assert_eq!(parse_quantity("12x"), None);
        assert_eq!(parse_quantity(""), None);
    }

    #[test]
    fn a_gang_that_fits_is_admitted_and_one_that_does_not_waits() {
        let view = |used_cpu: &str| QueueView {
            runs: vec![run("me", 0, Phase::Queued)],
            quotas: vec![quota(&[("requests.cpu", "4"), ("pods", "10")], &[("requests.cpu", used_cpu), ("pods", "2")])],
            max_concurrent_runs: 0,
        };
        assert_eq!(admit("me", at(0), GANG, &view("1500m")), Admission::Admitted);
        match admit("me", at(0), GANG, &view("2500m")) {
            Admission::Waiting { reason, message } => {
                assert_eq!(reason, "QuotaExceeded");
                assert!(message.contains("requests.cpu") && message.contains("1500m free"), "{message}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn fifo_per_namespace_and_kueue_runs_do_not_count() {
        let mut view = QueueView {
            runs: vec![run("older", 0, Phase::Queued), run("me", 5, Phase::Queued), run("newer", 9, Phase::Queued)],
            quotas: vec![],
            max_concurrent_runs: 0,
        };
        assert!(matches!(admit("me", at(5), GANG, &view), Admission::Waiting { reason: "WaitingForEarlierRuns", .. }));
        assert_eq!(admit("older", at(0), GANG, &view), Admission::Admitted);
        view.runs[0].kueue = true;
        assert_eq!(admit("me", at(5), GANG, &view), Admission::Admitted);
    }

    #[test]
    fn max_concurrent_runs_counts_active_runs() {
        let view = QueueView {
            runs: vec![run("a", 0, Phase::Running), run("b", 1, Phase::Succeeded), run("me", 5, Phase::Queued)],
            quotas: vec![],
            max_concurrent_runs: 1,
        };
        assert!(matches!(admit("me", at(5), GANG, &view), Admission::Waiting { reason: "MaxConcurrentRuns", .. }));
        let unlimited = QueueView { max_concurrent_runs: 0, ..view.clone() };
        assert_eq!(admit("me", at(5), GANG, &unlimited), Admission::Admitted);
    }

    #[test]
    fn runs_generating_assets_reserve_their_gang() {
        let mut starting = run("a", 0, Phase::GeneratingAssets);
        starting.gang = Some(GANG);
        let view = QueueView {
            runs: vec![starting, run("me", 5, Phase::Queued)],
            quotas: vec![quota(&[("pods", "6")], &[("pods", "1")])],
            max_concurrent_runs: 0,
        };
        // 6 - 1 used - 4 reserved = 1 free < 4 needed.
        assert!(matches!(admit("me", at(5), GANG, &view), Admission::Waiting { reason: "QuotaExceeded", .. }));
    }
}
