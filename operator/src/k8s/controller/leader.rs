//! Leader election with a `coordination.k8s.io/v1` Lease: one operator replica reconciles,
//! the others wait. The holder renews every [`RENEW_EVERY`]; a Lease not renewed for its
//! `leaseDurationSeconds` may be taken over. Every write carries the Lease's
//! `resourceVersion`, so two candidates never both win (the loser gets 409 Conflict).
//!
//! # Guarantees
//! A replica that cannot renew within the lease duration reports the loss, and the
//! operator stops reconciling and exits (the Deployment restarts it as a follower).

use std::time::Duration;

use k8s_openapi::api::coordination::v1::{Lease, LeaseSpec};
use k8s_openapi::apimachinery::pkg::apis::meta::v1::MicroTime;
use k8s_openapi::jiff::{SignedDuration, Timestamp};
use kube::api::{Api, ObjectMeta, PostParams};
use tokio::sync::watch;

/// Name of the Lease.
pub const LEASE_NAME: &str = "sadesim-operator";
/// Seconds a Lease stays valid without renewal.
pub const LEASE_DURATION_S: i32 = 15;
/// How often the holder renews, and how often a follower retries.
pub const RENEW_EVERY: Duration = Duration::from_secs(5);

/// What to do with the Lease as observed (pure).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Step {
    /// No Lease yet: create it holding it.
    Create,
    /// We hold it: renew.
    Renew,
    /// Another holder let it expire (or none holds it): take it over.
    Acquire,
    /// Someone else holds a valid Lease.
    Follow { holder: String },
}

/// Decides the step for candidate `me` at `now`.
pub fn step(lease: Option<&Lease>, me: &str, now: Timestamp) -> Step {
    let Some(lease) = lease else { return Step::Create };
    let spec = lease.spec.clone().unwrap_or_default();
    let holder = spec.holder_identity.unwrap_or_default();
    if holder == me {
        return Step::Renew;
    }
    let duration = SignedDuration::from_secs(i64::from(spec.lease_duration_seconds.unwrap_or(LEASE_DURATION_S)));
    let renewed = spec.renew_time.or(spec.acquire_time).map(|t| t.0);
    match renewed {
        Some(t) if !holder.is_empty() && t + duration > now => Step::Follow { holder },
        _ => Step::Acquire,
    }
}

fn held_spec(me: &str, now: Timestamp, acquired: Option<MicroTime>, transitions: i32) -> LeaseSpec {
    LeaseSpec {
        holder_identity: Some(me.to_string()),
        lease_duration_seconds: Some(LEASE_DURATION_S),
        acquire_time: Some(acquired.unwrap_or(MicroTime(now))),
        renew_time: Some(MicroTime(now)),
        lease_transitions: Some(transitions),
        ..Default::default()
    }
}

/// One round: reads the Lease and creates, renews or takes it over. `Ok(true)` when `me`
/// holds it afterwards.
///
/// # Errors
/// API errors other than a lost race (409 Conflict, which means "not the leader").
pub async fn round(leases: &Api<Lease>, me: &str) -> Result<bool, kube::Error> {
    let now = Timestamp::now();
    let current = leases.get_opt(LEASE_NAME).await?;
    let result = match step(current.as_ref(), me, now) {
        Step::Follow { .. } => return Ok(false),
        Step::Create => {
            let lease = Lease {
                metadata: ObjectMeta { name: Some(LEASE_NAME.into()), ..Default::default() },
                spec: Some(held_spec(me, now, None, 0)),
            };
            leases.create(&PostParams::default(), &lease).await.map(|_| ())
        }
        Step::Renew | Step::Acquire => {
            let mut lease = current.expect("a lease to renew or acquire exists");
            let old = lease.spec.clone().unwrap_or_default();
            let renewing = old.holder_identity.as_deref() == Some(me);
            let transitions = old.lease_transitions.unwrap_or(0) + i32::from(!renewing);
            let acquired = if renewing { old.acquire_time } else { None };
            lease.spec = Some(held_spec(me, now, acquired, transitions));
            // `replace` sends the resourceVersion read above: optimistic concurrency.
            leases.replace(LEASE_NAME, &PostParams::default(), &lease).await.map(|_| ())
        }
    };
    match result {
        Ok(()) => Ok(true),
        Err(kube::Error::Api(e)) if e.code == 409 => Ok(false),
        Err(e) => Err(e),
    }
}

/// Waits until `me` leads (or `stop` fires: `false`), then keeps renewing in the
/// background; the returned receiver turns `false` when leadership is lost.
pub async fn acquire(leases: Api<Lease>, me: String, mut stop: watch::Receiver<bool>) -> Option<watch::Receiver<bool>> {
    let mut logged_follow = false;
    loop {
        match round(&leases, &me).await {
            Ok(true) => break,
            Ok(false) => {
                if !logged_follow {
                    super::log::info("waiting for leadership", &[("lease", LEASE_NAME), ("identity", &me)]);
                    logged_follow = true;
                }
            }
            Err(e) => super::log::warn("leader election failed", &[("error", &e.to_string())]),
        }
        tokio::select! {
            _ = tokio::time::sleep(RENEW_EVERY) => {}
            _ = stop.changed() => return None,
        }
    }
    super::log::info("leading", &[("lease", LEASE_NAME), ("identity", &me)]);
    let (tx, rx) = watch::channel(true);
    tokio::spawn(async move {
        let mut last_renewal = tokio::time::Instant::now();
        let lease_duration = Duration::from_secs(LEASE_DURATION_S as u64);
        loop {
            tokio::select! {
                _ = tokio::time::sleep(RENEW_EVERY) => {}
                _ = stop.changed() => return,
            }
            match round(&leases, &me).await {
                Ok(true) => last_renewal = tokio::time::Instant::now(),
                Ok(false) => {
                    super::log::error("lost leadership: another replica holds the lease", &[("lease", LEASE_NAME)]);
                    let _ = tx.send(false);
                    return;
                }
                Err(e) => {
                    super::log::warn("lease renewal failed", &[("error", &e.to_string())]);
                    if last_renewal.elapsed() >= lease_duration {
                        super::log::error("lost leadership: lease not renewed in time", &[("lease", LEASE_NAME)]);
                        let _ = tx.send(false);
                        return;
                    }
                }
            }
        }
    });
    Some(rx)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lease(holder: &str, renewed_s_ago: i64, now: Timestamp) -> Lease {
        Lease {
            metadata: ObjectMeta { name: Some(LEASE_NAME.into()), ..Default::default() },
            spec: Some(LeaseSpec {
                holder_identity: Some(holder.into()),
                lease_duration_seconds: Some(LEASE_DURATION_S),
                renew_time: Some(MicroTime(now - SignedDuration::from_secs(renewed_s_ago))),
                ..Default::default()
            }),
        }
    }

    #[test]
    fn create_renew_follow_and_take_over() {
        let now = Timestamp::from_second(1_800_000_000).unwrap();
        assert_eq!(step(None, "me", now), Step::Create);
        assert_eq!(step(Some(&lease("me", 3, now)), "me", now), Step::Renew);
        assert_eq!(step(Some(&lease("other", 3, now)), "me", now), Step::Follow { holder: "other".into() });
        assert_eq!(step(Some(&lease("other", 16, now)), "me", now), Step::Acquire);
        assert_eq!(step(Some(&lease("", 1, now)), "me", now), Step::Acquire);
    }
}
