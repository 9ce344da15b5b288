//! Contacts between drones and the city, with rapier3d.
//!
//! Each shard keeps one rapier world (DESIGN §6: one world per shard amortises rapier's
//! fixed per-step cost): every building is a fixed collider built from its prism (see
//! [`building_collider`]), every drone a kinematic body carrying a ball sensor of its
//! rotor-disc radius.
//!
//! Frame and units: rapier's world frame is the world ENU frame, metres (x east, y north,
//! z up); no scaling. The drones' motion is
//! integrated by the vehicle model (`vehicle::RigidState`, exact rigid-body equations the
//! controllers are tuned on); rapier moves the kinematic bodies to the new poses and its
//! broad and narrow phases report which drones now overlap a building. Drone-drone contact
//! is deliberately not modelled here: drones of other shards are not in this world, and a
//! trajectory must not depend on sharding (DESIGN §5); separation is judged on the merged
//! snapshot instead.

use nalgebra::Vector3;
use rapier3d_f64::prelude::{
    ActiveCollisionTypes, ColliderBuilder, ColliderHandle, PhysicsWorld, Pose, RigidBodyBuilder, RigidBodyHandle,
    SharedShape, Vector,
};

use sadesim_world::{Building, Point2};

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
        for collider in buildings.iter().filter_map(building_collider) {
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

/// The fixed collider of one building's prism, in world ENU metres.
///
/// - An axis-aligned rectangle (every procedural building): a cuboid, exactly as the boxes
///   had it (same centre and half extents, bit for bit), so flights near buildings do not
///   change.
/// - A convex footprint: the convex hull of the prism's corners.
/// - A concave footprint or one with holes: a compound of convex prisms over the
///   footprint's vertical-slab trapezoids ([`sadesim_world::Footprint::convex_pieces`]).
///   Chosen over a triangle mesh because the pieces are solid: a drone wholly inside a
///   building still overlaps it (as `World::is_inside_building` says), where a trimesh is
///   a surface only touched while crossing it; and the decomposition is exact (no
///   approximation as with V-HACD) and needs no triangulation of a roof with holes.
///
/// Convex shapes are built in a local frame at the bounding box's centre, half-way up (ENU
/// axes), then translated: hull computation on coordinates of a few tens of metres rather
/// than kilometres. `None` only when no piece yields a hull (a validated footprint with a
/// positive height always does).
pub fn building_collider(b: &Building) -> Option<ColliderBuilder> {
    let half_up_m = b.height_m() / 2.0;
    if let Some(r) = b.footprint().axis_rect() {
        let center = Vector3::new(r.center_east_m, r.center_north_m, b.base_up_m() + b.height_m() / 2.0);
        return Some(ColliderBuilder::cuboid(r.half_east_m, r.half_north_m, half_up_m).translation(v(&center)));
    }
    let [ce, cn] = b.footprint().bounds_center();
    let origin = Vector3::new(ce, cn, b.base_up_m() + half_up_m);
    let corners = |ring: &[Point2]| -> Vec<Vector> {
        ring.iter()
            .flat_map(|p| [Vector::new(p[0] - ce, p[1] - cn, -half_up_m), Vector::new(p[0] - ce, p[1] - cn, half_up_m)])
            .collect()
    };
    let shape = if b.footprint().is_convex() {
        SharedShape::convex_hull(&corners(b.footprint().outer()))?
    } else {
        let parts: Vec<(Pose, SharedShape)> = b
            .footprint()
            .convex_pieces()
            .iter()
            .filter_map(|piece| SharedShape::convex_hull(&corners(piece)))
            .map(|hull| (Pose::IDENTITY, hull))
            .collect();
        if parts.is_empty() {
            return None;
        }
        SharedShape::compound(parts)
    };
    Some(ColliderBuilder::new(shape).translation(v(&origin)))
}

#[cfg(test)]
mod tests {
    use sadesim_world::Footprint;

    use super::*;

    fn tower() -> Building {
        let square = vec![[40.0, -10.0], [60.0, -10.0], [60.0, 10.0], [40.0, 10.0]];
        Building::new(Footprint::new(square, vec![]).unwrap(), 0.0, 60.0).unwrap()
    }

    /// An L: the 30 m square at the origin without its north-east 20 m quarter; roof 20 m.
    fn l_shape() -> Building {
        let outer = vec![[0.0, 0.0], [30.0, 0.0], [30.0, 10.0], [10.0, 10.0], [10.0, 30.0], [0.0, 30.0]];
        Building::new(Footprint::new(outer, vec![]).unwrap(), 0.0, 20.0).unwrap()
    }

    /// A 40 m block at the origin around a 20 m courtyard, on ground at 2 m; roof at 17 m.
    fn courtyard() -> Building {
        let outer = vec![[0.0, 0.0], [40.0, 0.0], [40.0, 40.0], [0.0, 40.0]];
        let hole = vec![[10.0, 10.0], [30.0, 10.0], [30.0, 30.0], [10.0, 30.0]];
        Building::new(Footprint::new(outer, vec![hole]).unwrap(), 2.0, 15.0).unwrap()
    }

    /// A diamond (convex, not axis-aligned) centred at (100, 100), 10 m to each corner.
    fn diamond() -> Building {
        let outer = vec![[100.0, 90.0], [110.0, 100.0], [100.0, 110.0], [90.0, 100.0]];
        Building::new(Footprint::new(outer, vec![]).unwrap(), 0.0, 30.0).unwrap()
    }

    /// Drops a ball of `radius_m` from 40 m straight down at (east, north) in 5 cm steps and
    /// returns the height of its centre at first contact, or `None`.
    fn drop_ball(building: &Building, east_m: f64, north_m: f64, radius_m: f64) -> Option<f64> {
        let mut w =
            ContactWorld::new(std::slice::from_ref(building), &[(Vector3::new(east_m, north_m, 40.0), radius_m)]);
        (0..=800).map(|k| 40.0 - 0.05 * k as f64).find(|&z| {
            w.set_position(0, &Vector3::new(east_m, north_m, z));
            w.step();
            w.touches_building(0)
        })
    }

    #[test]
    fn a_procedural_rectangle_keeps_its_exact_cuboid() {
        let collider = building_collider(&tower()).unwrap().build();
        let cuboid = collider.shape().as_cuboid().expect("an axis-aligned footprint is a cuboid");
        assert_eq!(cuboid.half_extents, Vector::new(10.0, 10.0, 30.0));
        assert_eq!(collider.translation(), Vector::new(50.0, 0.0, 30.0));
        assert!(building_collider(&diamond()).unwrap().build().shape().as_convex_polyhedron().is_some());
        assert!(building_collider(&courtyard()).unwrap().build().shape().as_compound().is_some());
    }

    #[test]
    fn a_ball_falling_into_a_courtyard_does_not_touch_and_one_over_the_wing_does() {
        let b = courtyard();
        assert_eq!(drop_ball(&b, 20.0, 20.0, 0.4), None, "the courtyard is open down to the ground");
        assert_eq!(drop_ball(&b, 11.0, 20.0, 0.4), None, "0.6 m clear of the courtyard's west wall");
        let z = drop_ball(&b, 5.0, 20.0, 0.4).expect("the west wing is solid");
        assert!((17.35..=17.4).contains(&z), "roof at 17 m, ball radius 0.4 m: first contact at {z}");
        let z = drop_ball(&b, 10.2, 20.0, 0.4).expect("grazes the courtyard's west wall");
        assert!(z <= 17.4 && z > 17.0, "{z}");
    }

    #[test]
    fn an_l_shape_is_solid_in_its_arms_and_open_in_its_notch() {
        let b = l_shape();
        assert_eq!(drop_ball(&b, 20.0, 20.0, 0.4), None, "the missing quarter");
        assert_eq!(drop_ball(&b, 11.0, 11.0, 0.4), None, "near the inner corner, 1 m off both walls");
        for (e, n) in [(5.0, 25.0), (25.0, 5.0), (5.0, 5.0)] {
            let z = drop_ball(&b, e, n, 0.4).expect("the arms are solid");
            assert!((20.35..=20.4).contains(&z), "{z}");
        }
    }

    #[test]
    fn contact_agrees_with_the_prism_distance_at_mid_height() {
        // Balls on a 1 m lattice at mid-height: a ball touches exactly when its centre is within
        // its radius of the footprint (away from the radius itself, where rounding decides).
        let radius_m = 0.4;
        for b in [l_shape(), courtyard(), diamond()] {
            let [lo_e, lo_n, hi_e, hi_n] = b.footprint().bounds();
            let z = b.base_up_m() + b.height_m() / 2.0;
            let mut balls = Vec::new();
            let mut e = lo_e - 2.0;
            while e <= hi_e + 2.0 {
                let mut n = lo_n - 2.0;
                while n <= hi_n + 2.0 {
                    balls.push((Vector3::new(e + 0.3, n + 0.7, z), radius_m));
                    n += 1.0;
                }
                e += 1.0;
            }
            let mut w = ContactWorld::new(std::slice::from_ref(&b), &balls);
            w.step();
            let mut touching = 0;
            for (i, (p, _)) in balls.iter().enumerate() {
                let d = b.footprint().distance_m(p.x, p.y);
                if (d - radius_m).abs() < 1e-3 {
                    continue;
                }
                assert_eq!(w.touches_building(i), d <= radius_m, "ball at {p:?}, {d} m from {b:?}");
                touching += usize::from(d <= radius_m);
            }
            assert!(touching > 100, "the lattice covers the building: {touching}");
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
