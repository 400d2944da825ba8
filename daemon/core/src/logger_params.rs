//! The logger's group of parameters: how much of the log disk a vehicle's logs may take (PX4's
//! `SDLOG_*`). The logs themselves are the daemon's; their limits are parameters like any other,
//! set from a ground station and kept in the store.

crate::params::param_group! {
    /// How many runs the log directory keeps, how much free space the logs leave on its disk,
    /// and how large one run's logs grow.
    LoggerGroup, "logger", LOGGER_META {
        /// Runs kept in the log directory.
        dirs_max: u32 = 0, "SDLOG_DIRS_MAX", "", [0.0, 100000.0], "Runs kept in the log directory: at start-up the oldest runs' logs are removed beyond this many, the new run included (0: as many as SDLOG_MIN_FREE leaves room for)";
        /// Free space the logs leave on their disk (MB).
        min_free_mb: u32 = 50, "SDLOG_MIN_FREE", "MB", [0.0, 1000000.0], "Free space the logs leave on their disk: at start-up the oldest runs' logs are removed until there is this much; in flight the logs stop cleanly below it and the ground station is told (0: none kept)";
        /// The size at which a log file goes on in a new part (MB).
        max_size_mb: u32 = 512, "SDLOG_MAX_SIZE", "MB", [0.0, 1000000.0], "Size at which a log file (ULog, CSV, telemetry log) goes on in a new part, NAME.2.ulg and so on, each part whole and readable on its own (0: one file, however long the run)";
        /// Parts of each log file kept (the newest).
        rotate: u32 = 4, "SDLOG_ROTATE", "", [0.0, 100000.0], "Parts of each log file a run keeps, the newest: a new part removes the oldest beyond this many, so one run's logs take at most SDLOG_MAX_SIZE times this per file (0: every part kept)";
    }
}
