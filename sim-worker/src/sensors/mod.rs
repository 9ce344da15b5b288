//! Sensor models: IMU, barometer, magnetometer, GNSS receiver.
