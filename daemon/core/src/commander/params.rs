//! The commander's parameters.

crate::params::param_group! {
    /// What to fly, and the commander's limits. Names and types are PX4's where PX4 has the
    /// parameter (`MIS_TAKEOFF_ALT`, `RTL_RETURN_ALT`, …), so that ground stations and MAVSDK
    /// find them where they look.
    CommanderParams, "commander", COMMANDER_META {
        /// Take-off altitude above home (m).
        takeoff_alt_m: f64 = 2.5, "MIS_TAKEOFF_ALT", "m", [0.5, 100.0], "Take-off altitude above home";
        /// Climb speed of the take-off set-point (m/s).
        takeoff_speed_m_s: f64 = 1.5, "MPC_TKO_SPEED", "m/s", [0.3, 5.0], "Climb speed of the take-off";
        /// Time the take-off climb takes to reach its speed (s).
        takeoff_ramp_s: f64 = 1.5, "MPC_TKO_RAMP_T", "s", [0.1, 10.0], "Time the take-off climb takes to reach MPC_TKO_SPEED (also the Return's climb): a gentle lift into the wind, whatever MPC_ACC_HOR";
        /// Spool-up time on the ground after arming (s).
        spool_s: f64 = 1.0, "COM_SPOOLUP_TIME", "s", [0.0, 30.0], "Time on the ground after arming before a take-off climbs";
        /// Descent speed while landing (m/s).
        land_speed_m_s: f64 = 0.7, "MPC_LAND_SPEED", "m/s", [0.1, 3.0], "Descent speed while landing";
        /// Descent speed for the last part of the landing (m/s), as PX4's two-stage landing.
        final_speed_m_s: f64 = 0.3, "MPC_LAND_CRWL", "m/s", [0.1, 3.0], "Descent speed for the last metres of a landing";
        /// Height above home where the final, slower descent begins (m).
        final_height_m: f64 = 2.0, "MPC_LAND_ALT3", "m", [0.0, 20.0], "Height above home below which a landing descends at MPC_LAND_CRWL";
        /// Return altitude above home (m).
        rtl_return_alt_m: f64 = 30.0, "RTL_RETURN_ALT", "m", [0.0, 500.0], "Return altitude above home (a vehicle higher up returns at its altitude)";
        /// Horizontal cruise speed of automatic flight (m/s).
        cruise_speed_m_s: f64 = 5.0, "MPC_XY_CRUISE", "m/s", [0.5, 20.0], "Horizontal speed of automatic flight";
        /// Acceleration of the automatic set-point profiles (m/s²).
        accel_m_s2: f64 = 3.0, "MPC_ACC_HOR", "m/s^2", [0.2, 15.0], "Acceleration of the automatic set-point profiles (the take-off's: MPC_TKO_RAMP_T)";
        /// Jerk of the automatic set-point profiles (m/s³).
        jerk_m_s3: f64 = 6.0, "MPC_JERK_AUTO", "m/s^3", [1.0, 80.0], "Jerk of the automatic set-point profiles: the acceleration ramps at this rate (S-curves), the take-off's too";
        /// Deceleration of a failsafe's stop (m/s²).
        failsafe_brake_m_s2: f64 = 2.5, "MPC_ACC_FS_BRK", "m/s^2", [0.5, 15.0], "Deceleration of a failsafe's Hold (a fence breach, a lost link): it holds where the vehicle stops at this rate, not at the gentle MPC_ACC_HOR";
        /// Disarm when armed on the ground this long without taking off (s; 0: never).
        disarm_preflight_s: f64 = 10.0, "COM_DISARM_PRFLT", "s", [0.0, 3600.0], "Disarm when armed on the ground this long without taking off (0: never)";
        /// Largest horizontal speed from the sticks in Posctl (m/s).
        manual_speed_m_s: f64 = 5.0, "MPC_VEL_MANUAL", "m/s", [0.5, 20.0], "Horizontal speed at full stick in position mode";
        /// Largest tilt from the sticks in Altctl (deg).
        manual_tilt_deg: f64 = 35.0, "MPC_MAN_TILT_MAX", "deg", [1.0, 70.0], "Tilt at full stick in altitude, stabilized and manual modes";
        /// Yaw rate at full stick (deg/s).
        manual_yaw_rate_deg_s: f64 = 150.0, "MPC_MAN_Y_MAX", "deg/s", [0.0, 400.0], "Yaw rate at full stick";
        /// Climb rate at full throttle stick (m/s).
        manual_climb_m_s: f64 = 3.0, "MAN_Z_VEL_UP", "m/s", [0.3, 10.0], "Climb rate at full throttle stick in altitude and position modes";
        /// Descent rate at zero throttle stick (m/s).
        manual_sink_m_s: f64 = 1.0, "MAN_Z_VEL_DN", "m/s", [0.3, 10.0], "Descent rate at zero throttle stick in altitude and position modes";
        /// Stick dead zone around the centre (fraction of full travel).
        stick_deadzone: f64 = 0.1, "MPC_HOLD_DZ", "", [0.0, 0.5], "Stick dead zone around the centre, where the vehicle holds";
        /// Manual control older than this is lost (s).
        manual_loss_s: f64 = 0.5, "COM_RC_LOSS_T", "s", [0.1, 35.0], "Manual control lost after this long without sticks (RC or MANUAL_CONTROL): manual modes switch to NAV_RCL_ACT's";
        /// What flies when the sticks are lost in a manual mode.
        manual_loss_action: u32 = 2, "NAV_RCL_ACT", "", [1.0, 3.0], "Manual control lost in a manual mode: 1 Hold, 2 Return (Hold without a home), 3 Land";
        /// Thrust at zero throttle stick in the stick-to-attitude modes (fraction of full thrust).
        manual_thrust_min: f64 = 0.08, "MPC_MANTHR_MIN", "", [0.0, 0.3], "Thrust at zero throttle stick in Stabilized and Manual (fraction of full thrust)";
        /// Offboard set-points older than this are lost (s).
        offboard_loss_s: f64 = 0.5, "COM_OF_LOSS_T", "s", [0.05, 60.0], "Offboard set-points lost after this long without one: COM_OBL_RC_ACT takes over";
        /// What flies when the offboard set-points stop.
        offboard_loss_action: u32 = 0, "COM_OBL_RC_ACT", "", [0.0, 5.0], "Offboard loss: 0 Position, 1 Altitude, 2 Manual (each Hold without a joystick), 3 Return, 4 Land, 5 Hold";
        /// Horizontal acceptance radius of mission waypoints that give none (m).
        acceptance_m: f64 = 2.0, "NAV_ACC_RAD", "m", [0.05, 200.0], "Horizontal acceptance radius of mission waypoints that give none; a waypoint without a hold is flown through on the arc touching both legs this far from it";
        /// Vertical acceptance of mission waypoints (m).
        alt_acceptance_m: f64 = 0.8, "NAV_MC_ALT_RAD", "m", [0.05, 200.0], "Vertical acceptance radius of mission waypoints";
        /// Climb speed of automatic flight (m/s).
        auto_climb_m_s: f64 = 3.0, "MPC_Z_V_AUTO_UP", "m/s", [0.5, 8.0], "Climb speed of missions and repositions";
        /// Descent speed of automatic flight (m/s).
        auto_sink_m_s: f64 = 1.5, "MPC_Z_V_AUTO_DN", "m/s", [0.5, 4.0], "Descent speed of missions and repositions";
        /// Yaw rate of automatic flight (deg/s).
        auto_yaw_rate_deg_s: f64 = 45.0, "MPC_YAWRAUTO_MAX", "deg/s", [5.0, 360.0], "Yaw rate of missions, repositions and CONDITION_YAW";
        /// Largest orbit radius (m).
        orbit_radius_max_m: f64 = 1000.0, "MC_ORBIT_RAD_MAX", "m", [1.0, 10000.0], "Largest radius of an orbit (DO_ORBIT)";
        /// Follow target: height (m).
        follow_height_m: f64 = 8.0, "FLW_TGT_HT", "m", [8.0, 500.0], "Follow target: height above home (FLW_TGT_ALT_M 0) or above the target (2)";
        /// Follow target: distance (m).
        follow_distance_m: f64 = 8.0, "FLW_TGT_DST", "m", [1.0, 100.0], "Follow target: horizontal distance from the target";
        /// Follow target: angle from the target's course (deg).
        follow_angle_deg: f64 = 180.0, "FLW_TGT_FA", "deg", [-180.0, 180.0], "Follow target: angle from the target's course, clockwise (0 ahead, 180 behind)";
        /// Follow target: responsiveness (0–1).
        follow_responsiveness: f64 = 0.1, "FLW_TGT_RS", "", [0.0, 1.0], "Follow target: responsiveness of the target filter, 0.1 to 1 (lower follows the fixes more closely)";
        /// Follow target: altitude mode.
        follow_altitude_mode: u32 = 0, "FLW_TGT_ALT_M", "", [0.0, 2.0], "Follow target: altitude 0 above home, 1 above terrain (as 0: no distance sensor), 2 above the target";
        /// Follow target: fastest turn about the target (m/s).
        follow_max_speed_m_s: f64 = 5.0, "FLW_TGT_MAX_VEL", "m/s", [0.1, 20.0], "Follow target: fastest speed round the target when its course turns";
        /// Centripetal acceleration that bounds an orbit's speed (m/s²).
        orbit_accel_m_s2: f64 = 3.0, "MC_ORBIT_ACC_MAX", "m/s^2", [0.5, 10.0], "Centripetal acceleration of an orbit: its speed is at most sqrt(this x radius)";
    }
}

impl CommanderParams {
    /// The take-off climb's acceleration (m/s²): `MPC_TKO_SPEED` reached in `MPC_TKO_RAMP_T`.
    pub fn takeoff_accel_m_s2(&self) -> f64 {
        self.takeoff_speed_m_s / self.takeoff_ramp_s.max(0.1)
    }
}
