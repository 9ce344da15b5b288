//! Environment factors sampled at (position, time): wind, GNSS conditions.
