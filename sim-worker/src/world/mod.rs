//! Ground, buildings and open areas around the origin (procedural city).
