//! Urban wind (the paper's first environment factor, §3.3): the wind around the world's
//! buildings on a 3-D grid aligned with the run's ENU frame.
