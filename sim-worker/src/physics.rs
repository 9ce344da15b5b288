//! Contacts between drones and the city, with rapier3d.
//!
//! Each shard keeps one rapier world (DESIGN §6: one world per shard amortises rapier's
//! fixed per-step cost): every building is a fixed cuboid collider, every drone a
//! kinematic body carrying a ball sensor of its rotor-disc radius. The drones' motion is
//! integrated by the vehicle model (`vehicle::RigidState`, exact rigid-body equations the
//! controllers are tuned on); rapier moves the kinematic bodies to the new poses and its
//! broad and narrow phases report which drones now overlap a building. Drone-drone contact
//! is deliberately not modelled here: drones of other shards are not in this world, and a
//! trajectory must not depend on sharding (DESIGN §5); separation is judged on the merged
//! snapshot instead.

use nalgebra::Vector3;
use rapier3d_f64::prelude::{
    ActiveCollisionTypes, ColliderBuilder, ColliderHandle, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle, Vector,
};

use sadesim_world::Building;

/// A shard's collision world.
pub struct ContactWorld {
    world: PhysicsWorld,
    drones: Vec<(RigidBodyHandle, ColliderHandle)>,
}

impl std::fmt::Debug for ContactWorld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ContactWorld").field("drones", &self.drones.len()).finish()
    }
}

fn v(p: &Vector3<f64>) -> Vector {
    Vector::new(p.x, p.y, p.z)
}

impl ContactWorld {
    /// Builds the world from the city's buildings and one ball of `radius_m` per drone at
    /// its start position.
    pub fn new(buildings: &[Building], drones: &[(Vector3<f64>, f64)]) -> Self {
        let mut world = PhysicsWorld { gravity: Vector::ZERO, ..PhysicsWorld::default() };
        for b in buildings {
            let center = Vector3::new(b.center_east_m, b.center_north_m, b.base_up_m + b.height_m / 2.0);
            let collider =
                ColliderBuilder::cuboid(b.half_east_m, b.half_north_m, b.height_m / 2.0).translation(v(&center));
            world.insert_collider(collider, None);
        }
        let drones = drones
            .iter()
            .map(|(p, radius_m)| {
                let body = RigidBodyBuilder::kinematic_position_based().translation(v(p));
                let collider = ColliderBuilder::ball(*radius_m)
                    .sensor(true)
                    // Kinematic vs fixed pairs are off by default in rapier: we need exactly those.
                    .active_collision_types(ActiveCollisionTypes::default() | ActiveCollisionTypes::KINEMATIC_FIXED);
                world.insert(body, collider)
            })
            .collect();
        Self { world, drones }
    }

    /// Moves drone `i` (shard-local index) to its new position.
    pub fn set_position(&mut self, i: usize, p: &Vector3<f64>) {
        let (body, _) = self.drones[i];
        self.world.bodies[body].set_translation(v(p), false);
    }

    /// Updates collision detection (broad and narrow phase only: rapier integrates nothing
    /// here, so its solver and its worker threads never run); call once per physics step
    /// after `set_position`.
    pub fn step(&mut self) {
        self.world.detect_collisions(&(), &());
    }

    /// Whether drone `i` overlaps any building.
    pub fn touches_building(&self, i: usize) -> bool {
        let (_, collider) = self.drones[i];
        self.world.narrow_phase.intersection_pairs_with(collider).any(|(_, _, intersecting)| intersecting)
    }

    /// Removes drone `i` from collision detection (after a crash).
    pub fn disable(&mut self, i: usize) {
        let (body, _) = self.drones[i];
        self.world.bodies[body].set_enabled(false);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tower() -> Building {
        Building {
            center_east_m: 50.0,
            center_north_m: 0.0,
            half_east_m: 10.0,
            half_north_m: 10.0,
            base_up_m: 0.0,
            height_m: 60.0,
        }
    }

    #[test]
    fn a_drone_flying_into_a_building_touches_it_and_one_above_does_not() {
        let mut w =
            ContactWorld::new(&[tower()], &[(Vector3::new(0.0, 0.0, 30.0), 0.4), (Vector3::new(50.0, 0.0, 70.0), 0.4)]);
        let mut hit_at = None;
        for step in 0..1000 {
            let x = step as f64 * 0.05; // 50 m/s east, 1 ms steps
            w.set_position(0, &Vector3::new(x, 0.0, 30.0));
            w.set_position(1, &Vector3::new(50.0 + x * 0.01, 0.0, 70.0));
            w.step();
            if hit_at.is_none() && w.touches_building(0) {
                hit_at = Some(x);
            }
            assert!(!w.touches_building(1), "60 m tower, drone at 70 m");
        }
        let x = hit_at.expect("drone 0 hits the tower's west face at x = 40 m");
        assert!((39.5..=40.1).contains(&x), "first contact at {x} (face at 40, ball radius 0.4)");
    }
}
