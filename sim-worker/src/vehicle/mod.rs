//! Airframes, motors and the forces on a multirotor.
