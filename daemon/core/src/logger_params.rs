//! The logger's group of parameters: how much of the log disk a vehicle's logs may take (PX4's
//! `SDLOG_*`). The logs themselves are the daemon's; their limits are parameters like any other,
//! set from a ground station and kept in the store.

crate::params::param_group! {
    /// How many runs the log directory keeps and how much free space the logs leave on its disk.
    LoggerGroup, "logger", LOGGER_META {
        /// Runs kept in the log directory.
        dirs_max: u32 = 0, "SDLOG_DIRS_MAX", "", [0.0, 100000.0], "Runs kept in the log directory: at start-up the oldest runs' logs are removed beyond this many, the new run included (0: as many as SDLOG_MIN_FREE leaves room for)";
        /// Free space the logs leave on their disk (MB).
        min_free_mb: u32 = 50, "SDLOG_MIN_FREE", "MB", [0.0, 1000000.0], "Free space the logs leave on their disk: at start-up the oldest runs' logs are removed until there is this much; in flight the logs stop cleanly below it and the ground station is told (0: none kept)";
    }
}
