//! Deterministic port plan.
//!
//! PX4 SITL conventions where they exist, so SDK defaults work unchanged:
//!
//! | what | port | why |
//! |---|---|---|
//! | drone i API/offboard link (drone sends, pilot listens) | 14540+i for i < 10, 14600+i for i >= 10 | PX4 SITL uses 14540+i; 14550.. is kept for the GCS |
//! | drone i endpoint (pilot connects: `udpout`/`tcpout`) | 24600+i, UDP and TCP | one free range above every API port |
//! | router segment s, GCS UDP | 14550+s | QGroundControl listens on 14550 |
//! | router segment s, GCS TCP | 5760+s | the SITL TCP convention |
//!
//! With the maximum of 10 000 drones: API ports 14540..14549 and 14610..24599, GCS UDP
//! 14550..14589, endpoints 24600..34599: no overlap. (PX4 itself collides at instance 10,
//! whose API port 14550 is QGroundControl's; we shift instead.)

use sadesim_crds::fleet::MAX_DRONES;
use sadesim_crds::plan::ServicePorts;

/// MAVLink system ids per router segment (1..=250; 251..=255 are left for ground stations
/// and companions, e.g. MAVSDK's 245 and QGroundControl's 255).
pub const SYSTEM_IDS_PER_SEGMENT: u32 = 250;
/// Segments needed for the largest fleet.
pub const MAX_SEGMENTS: u32 = MAX_DRONES.div_ceil(SYSTEM_IDS_PER_SEGMENT);

const API_BASE: u32 = 14540;
const API_SHIFTED_BASE: u32 = 14600;
const ENDPOINT_BASE: u32 = 24600;
const GCS_UDP_BASE: u32 = 14550;
const GCS_TCP_BASE: u32 = 5760;

/// Port drone `index` sends its API link to on the pilot's host.
pub fn api_udp_port(index: u32) -> u16 {
    let port = if index < 10 { API_BASE + index } else { API_SHIFTED_BASE + index };
    u16::try_from(port).expect("index < MAX_DRONES keeps ports below 65536")
}

/// Port drone `index` listens on (UDP and TCP) for clients that connect to it.
pub fn endpoint_port(index: u32) -> u16 {
    u16::try_from(ENDPOINT_BASE + index).expect("index < MAX_DRONES keeps ports below 65536")
}

/// GCS UDP port of router segment `segment`.
pub fn gcs_udp_port(segment: u32) -> u16 {
    u16::try_from(GCS_UDP_BASE + segment).expect("segment < MAX_SEGMENTS")
}

/// GCS TCP port of router segment `segment`.
pub fn gcs_tcp_port(segment: u32) -> u16 {
    u16::try_from(GCS_TCP_BASE + segment).expect("segment < MAX_SEGMENTS")
}

/// Ports of the run-wide services (the same locally and in every pod).
pub fn service_ports() -> ServicePorts {
    ServicePorts { coordinator: 7400, airspace_http: 8480, renderer_http: 8490, metrics: 9090 }
}

/// Moves every MAVLink port of `plan` (drones' API and endpoint ports, the routers' GCS
/// ports) up by `offset`, so several local runs can fly at once (`sadesim sweep`): each
/// run's fleet file names its own ports. Service ports are left alone: local runs fall
/// back to free ports for those.
///
/// # Errors
/// A port would pass 65535: the highest port it would need.
pub fn offset_ports(plan: &mut sadesim_crds::plan::RunPlan, offset: u16) -> Result<(), u32> {
    let shift = |p: &mut u16| -> Result<(), u32> {
        let moved = u32::from(*p) + u32::from(offset);
        *p = u16::try_from(moved).map_err(|_| moved)?;
        Ok(())
    };
    for d in &mut plan.drones {
        shift(&mut d.ports.api_udp)?;
        shift(&mut d.ports.endpoint)?;
    }
    for s in &mut plan.segments {
        shift(&mut s.gcs_udp)?;
        shift(&mut s.gcs_tcp)?;
    }
    Ok(())
}

/// Port offsets for `jobs` runs of at most `drones` drones flying at once on one host
/// (`sadesim sweep`): slot `k` moves its ports up by `k * (drones + 100)`. Every MAVLink
/// port range of every slot (GCS TCP, API and GCS UDP, endpoints) is checked disjoint from
/// every other.
///
/// # Errors
/// The ranges would overlap or pass 65535: how many runs of that size fit at once.
pub fn concurrent_offsets(drones: u32, jobs: u32) -> Result<Vec<u16>, String> {
    let stride = drones + 100;
    let segments = drones.div_ceil(SYSTEM_IDS_PER_SEGMENT).max(1);
    let ranges = |k: u32| {
        let o = k * stride;
        [
            (GCS_TCP_BASE + o, GCS_TCP_BASE + segments + o),
            (API_BASE + o, API_SHIFTED_BASE + drones + o),
            (ENDPOINT_BASE + o, ENDPOINT_BASE + drones + o),
        ]
    };
    let fits = |jobs: u32| {
        let all: Vec<(u32, u32)> = (0..jobs).flat_map(ranges).collect();
        all.iter().all(|r| r.1 <= 65_536)
            && all.iter().enumerate().all(|(i, a)| all[i + 1..].iter().all(|b| a.1 <= b.0 || b.1 <= a.0))
    };
    if fits(jobs) {
        return Ok((0..jobs).map(|k| (k * stride) as u16).collect());
    }
    let most = (1..jobs).rev().find(|j| fits(*j)).unwrap_or(0);
    Err(format!(
        "{jobs} runs of {drones} drones cannot fly at once on one host: their MAVLink ports would overlap (at most {most} fit); lower --jobs"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn concurrent_runs_get_disjoint_ports() {
        let offsets = concurrent_offsets(32, 8).unwrap();
        assert_eq!(offsets, [0, 132, 264, 396, 528, 660, 792, 924]);
        let mut plans: Vec<_> = offsets
            .iter()
            .map(|&o| {
                let run = sadesim_crds::fixtures::RunBuilder::test().with_drones(32).build();
                let mut plan = crate::plan(&run).unwrap();
                offset_ports(&mut plan, o).unwrap();
                plan
            })
            .collect();
        let mut seen = std::collections::BTreeSet::new();
        for plan in &mut plans {
            for d in &plan.drones {
                assert!(seen.insert(d.ports.api_udp) && seen.insert(d.ports.endpoint), "port reused");
            }
            for s in &plan.segments {
                assert!(seen.insert(s.gcs_udp) && seen.insert(s.gcs_tcp), "port reused");
            }
        }
    }

    #[test]
    fn too_many_concurrent_runs_are_refused_with_how_many_fit() {
        let e = concurrent_offsets(5000, 3).unwrap_err();
        assert!(e.contains("3 runs of 5000 drones cannot fly at once"), "{e}");
        assert!(e.contains("at most 1 fit"), "{e}");
    }
}
