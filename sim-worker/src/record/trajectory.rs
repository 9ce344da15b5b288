//! Trajectory files: CSV with one row per drone per sample (pandas, PlotJuggler,
//! spreadsheets), and GeoJSON LineStrings per drone (QGIS, geojson.io, kepler.gl).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use nalgebra::{Quaternion, UnitQuaternion};
use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::plan::RunPlan;
use serde_json::json;

use super::fixed;
use sadesim_engine::protocol::DroneSnapshot;

/// The CSV's name in the run folder.
pub const TRAJECTORY_CSV: &str = "trajectory.csv";

/// The GeoJSON's name in the run folder.
pub const TRAJECTORY_GEOJSON: &str = "trajectory.geojson";

/// Column names of `trajectory.csv`. Angles are Euler angles of the body (FLU) relative to
/// ENU: roll about x, pitch about y, yaw about z (0 = facing east, counter-clockwise).
pub const TRAJECTORY_CSV_HEADER: &str = "time_s,drone,name,group,latitude_deg,longitude_deg,altitude_msl_m,east_m,north_m,up_m,height_agl_m,vel_east_mps,vel_north_mps,vel_up_mps,roll_deg,pitch_deg,yaw_deg,mode,armed,on_ground,crashed,battery_remaining";

/// Writes `trajectory.csv`, flushing every sample.
#[derive(Debug)]
pub struct TrajectoryCsv {
    out: super::disk::Appender,
    /// The rows of one sample, built here and written at once (reused).
    rows: Vec<u8>,
}

impl TrajectoryCsv {
    /// Creates `dir/trajectory.csv` with its header.
    ///
    /// # Errors
    /// When the file cannot be created, naming it.
    pub fn create(dir: &Path) -> std::io::Result<Self> {
        let mut out = super::disk::Appender::create(dir, TRAJECTORY_CSV)?;
        out.write_all(format!("{TRAJECTORY_CSV_HEADER}\n").as_bytes())?;
        Ok(Self { out, rows: Vec::new() })
    }

    /// Closes the file at its last whole sample ([`super::disk::Appender::close`]).
    ///
    /// # Errors
    /// As [`super::disk::Appender::close`].
    pub fn close(self) -> std::io::Result<()> {
        self.out.close()
    }

    /// One row per drone at `time_s`. Numbers are written with [`fixed::push`], the same
    /// text as `format!("{:.N}")`.
    ///
    /// # Errors
    /// I/O errors.
    pub fn write(
        &mut self,
        time_s: f64,
        drones: &[DroneSnapshot],
        plan: &RunPlan,
        frame: &LocalFrame,
    ) -> std::io::Result<()> {
        let b = &mut self.rows;
        b.clear();
        for s in drones {
            let d = &plan.drones[s.index as usize];
            let [e, n, u] = s.position_enu_m;
            let g = frame.to_geodetic(Enu::new(e, n, u));
            let [w, x, y, z] = s.attitude_wxyz;
            let (roll, pitch, yaw) = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)).euler_angles();
            let [ve, vn, vu] = s.velocity_enu_mps;
            // time_s,drone,name,group,
            fixed::push(b, time_s, 3);
            write!(b, ",{},{},{},", s.index, d.name, d.group)?;
            // latitude_deg,...,battery_remaining: the header's order.
            let numbers = [
                (g.latitude_deg, 7),
                (g.longitude_deg, 7),
                (g.altitude_msl_m, 2),
                (e, 3),
                (n, 3),
                (u, 3),
                (s.height_agl_m, 3),
                (ve, 3),
                (vn, 3),
                (vu, 3),
                (roll.to_degrees(), 2),
                (pitch.to_degrees(), 2),
                (yaw.to_degrees(), 2),
            ];
            for (v, decimals) in numbers {
                fixed::push(b, v, decimals);
                b.push(b',');
            }
            write!(b, "{},{},{},{},", s.mode.as_str(), s.armed, s.on_ground, s.crashed)?;
            fixed::push(b, s.battery_remaining, 4);
            b.push(b'\n');
        }
        self.out.write_all(b)?;
        self.out.flush()
    }
}

/// Collects per-drone tracks and writes them as a GeoJSON FeatureCollection at the end.
#[derive(Debug)]
pub struct TrajectoryGeoJson {
    tracks: Vec<Vec<[f64; 3]>>,
}

impl TrajectoryGeoJson {
    pub fn new(drones: usize) -> Self {
        Self { tracks: vec![Vec::new(); drones] }
    }

    pub fn add(&mut self, drones: &[DroneSnapshot], frame: &LocalFrame) {
        for s in drones {
            let [e, n, u] = s.position_enu_m;
            let g = frame.to_geodetic(Enu::new(e, n, u));
            if let Some(track) = self.tracks.get_mut(s.index as usize) {
                track.push([g.longitude_deg, g.latitude_deg, g.altitude_msl_m]);
            }
        }
    }

    /// Writes the collection: one LineString per drone (`[lon, lat, alt_msl]`, RFC 7946)
    /// with the drone's name, group, operator and role.
    ///
    /// # Errors
    /// I/O errors.
    pub fn write(&self, path: &Path, plan: &RunPlan) -> std::io::Result<()> {
        let features: Vec<serde_json::Value> = self
            .tracks
            .iter()
            .zip(&plan.drones)
            .map(|(track, d)| {
                json!({
                    "type": "Feature",
                    "geometry": {"type": "LineString", "coordinates": track},
                    "properties": {"drone": d.index, "name": d.name, "group": d.group, "operator": d.operator, "role": d.role},
                })
            })
            .collect();
        let doc = json!({"type": "FeatureCollection", "features": features});
        let mut out = BufWriter::new(File::create(path)?);
        serde_json::to_writer(&mut out, &doc).map_err(std::io::Error::other)?;
        out.flush()
    }
}
