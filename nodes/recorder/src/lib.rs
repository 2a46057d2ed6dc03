//! rosbag2-compatible MCAP bags (work in progress).
