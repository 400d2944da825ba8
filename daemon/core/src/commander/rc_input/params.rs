//! The RC group of parameters.

crate::params::param_group! {
    /// The RC transmitter: which channel is which stick or switch, the mode switch's slots, how
    /// its sticks share with a joystick, and each channel's calibration (PX4's `RC_MAP_*`,
    /// `COM_FLTMODE*`, `COM_RC_*`, `RCn_*`).
    RcGroup, "rc", RC_META {
        /// Channel of the roll stick (0: none).
        map_roll: u32 = 1, "RC_MAP_ROLL", "", [0.0, 16.0], "RC channel of the roll stick (0: none)";
        /// Channel of the pitch stick.
        map_pitch: u32 = 2, "RC_MAP_PITCH", "", [0.0, 16.0], "RC channel of the pitch stick (0: none)";
        /// Channel of the throttle stick.
        map_throttle: u32 = 3, "RC_MAP_THROTTLE", "", [0.0, 16.0], "RC channel of the throttle stick (0: none)";
        /// Channel of the yaw stick.
        map_yaw: u32 = 4, "RC_MAP_YAW", "", [0.0, 16.0], "RC channel of the yaw stick (0: none)";
        /// Channel of the flight-mode switch.
        map_mode: u32 = 5, "RC_MAP_FLTMODE", "", [0.0, 16.0], "RC channel of the flight-mode switch, whose travel is cut in six slots (COM_FLTMODE1 to 6; 0: none)";
        /// Channel of the arm switch.
        map_arm: u32 = 0, "RC_MAP_ARM_SW", "", [0.0, 16.0], "RC channel of the arm switch (0: none; arm and disarm by the stick gesture)";
        /// Arm switch threshold.
        arm_threshold: f64 = 0.75, "RC_ARMSWITCH_TH", "", [0.0, 1.0], "Arm switch on above this fraction of its travel";
        /// Flight mode of switch slot 1.
        fltmode1: i32 = 2, "COM_FLTMODE1", "", [-1.0, 14.0], "Mode of the mode switch's slot 1 (-1 none, 0 Manual, 1 Altitude, 2 Position, 3 Mission, 4 Hold, 5 Return, 8 Stabilized, 10 Takeoff, 11 Land, 14 Orbit; default Position)";
        /// Flight mode of switch slot 2.
        fltmode2: i32 = 1, "COM_FLTMODE2", "", [-1.0, 14.0], "Mode of the mode switch's slot 2 (-1 none, 0 Manual, 1 Altitude, 2 Position, 3 Mission, 4 Hold, 5 Return, 8 Stabilized, 10 Takeoff, 11 Land, 14 Orbit; default Altitude)";
        /// Flight mode of switch slot 3.
        fltmode3: i32 = 8, "COM_FLTMODE3", "", [-1.0, 14.0], "Mode of the mode switch's slot 3 (-1 none, 0 Manual, 1 Altitude, 2 Position, 3 Mission, 4 Hold, 5 Return, 8 Stabilized, 10 Takeoff, 11 Land, 14 Orbit; default Stabilized)";
        /// Flight mode of switch slot 4.
        fltmode4: i32 = 4, "COM_FLTMODE4", "", [-1.0, 14.0], "Mode of the mode switch's slot 4 (-1 none, 0 Manual, 1 Altitude, 2 Position, 3 Mission, 4 Hold, 5 Return, 8 Stabilized, 10 Takeoff, 11 Land, 14 Orbit; default Hold)";
        /// Flight mode of switch slot 5.
        fltmode5: i32 = 5, "COM_FLTMODE5", "", [-1.0, 14.0], "Mode of the mode switch's slot 5 (-1 none, 0 Manual, 1 Altitude, 2 Position, 3 Mission, 4 Hold, 5 Return, 8 Stabilized, 10 Takeoff, 11 Land, 14 Orbit; default Return)";
        /// Flight mode of switch slot 6.
        fltmode6: i32 = 11, "COM_FLTMODE6", "", [-1.0, 14.0], "Mode of the mode switch's slot 6 (-1 none, 0 Manual, 1 Altitude, 2 Position, 3 Mission, 4 Hold, 5 Return, 8 Stabilized, 10 Takeoff, 11 Land, 14 Orbit; default Land)";
        /// Which stick inputs fly.
        input_mode: u32 = 3, "COM_RC_IN_MODE", "", [0.0, 4.0], "Stick input: 0 RC only, 1 joystick (MANUAL_CONTROL) only, 2 RC and joystick (RC first, the joystick when RC is lost), 3 whichever came first while it lasts, 4 none";
        /// Stick override of automatic modes.
        override_modes: u32 = 1, "COM_RC_OVERRIDE", "", [0.0, 3.0], "RC sticks moved beyond COM_RC_STICK_OV take over into Position mode from: 1 automatic modes, 2 offboard, 3 both, 0 neither";
        /// Stick override threshold.
        override_pct: f64 = 30.0, "COM_RC_STICK_OV", "%", [5.0, 80.0], "Stick deflection that takes over from an automatic mode (COM_RC_OVERRIDE)";
        /// Arm and disarm by the stick gesture.
        gesture: u32 = 1, "MAN_ARM_GESTURE", "", [0.0, 1.0], "Arm by throttle low and yaw right for a second, disarm on the ground by throttle low and yaw left (1), or not (0)";
        /// Channel 1: pulse at its lowest.
        rc1_min: f64 = 1000.0, "RC1_MIN", "us", [800.0, 1500.0], "RC channel 1: pulse at its lowest (from the radio calibration)";
        /// Channel 1: pulse at its centre.
        rc1_trim: f64 = 1500.0, "RC1_TRIM", "us", [800.0, 2200.0], "RC channel 1: pulse at its centre";
        /// Channel 1: pulse at its highest.
        rc1_max: f64 = 2000.0, "RC1_MAX", "us", [1500.0, 2200.0], "RC channel 1: pulse at its highest";
        /// Channel 1: reversed (-1) or not (1).
        rc1_rev: f64 = 1.0, "RC1_REV", "", [-1.0, 1.0], "RC channel 1: 1 as is, -1 reversed";
        /// Channel 1: dead zone about its centre.
        rc1_dz: f64 = 10.0, "RC1_DZ", "us", [0.0, 100.0], "RC channel 1: dead zone about its centre";
        /// Channel 2: pulse at its lowest.
        rc2_min: f64 = 1000.0, "RC2_MIN", "us", [800.0, 1500.0], "RC channel 2: pulse at its lowest (from the radio calibration)";
        /// Channel 2: pulse at its centre.
        rc2_trim: f64 = 1500.0, "RC2_TRIM", "us", [800.0, 2200.0], "RC channel 2: pulse at its centre";
        /// Channel 2: pulse at its highest.
        rc2_max: f64 = 2000.0, "RC2_MAX", "us", [1500.0, 2200.0], "RC channel 2: pulse at its highest";
        /// Channel 2: reversed (-1) or not (1).
        rc2_rev: f64 = 1.0, "RC2_REV", "", [-1.0, 1.0], "RC channel 2: 1 as is, -1 reversed";
        /// Channel 2: dead zone about its centre.
        rc2_dz: f64 = 10.0, "RC2_DZ", "us", [0.0, 100.0], "RC channel 2: dead zone about its centre";
        /// Channel 3: pulse at its lowest.
        rc3_min: f64 = 1000.0, "RC3_MIN", "us", [800.0, 1500.0], "RC channel 3: pulse at its lowest (from the radio calibration)";
        /// Channel 3: pulse at its centre.
        rc3_trim: f64 = 1500.0, "RC3_TRIM", "us", [800.0, 2200.0], "RC channel 3: pulse at its centre";
        /// Channel 3: pulse at its highest.
        rc3_max: f64 = 2000.0, "RC3_MAX", "us", [1500.0, 2200.0], "RC channel 3: pulse at its highest";
        /// Channel 3: reversed (-1) or not (1).
        rc3_rev: f64 = 1.0, "RC3_REV", "", [-1.0, 1.0], "RC channel 3: 1 as is, -1 reversed";
        /// Channel 3: dead zone about its centre.
        rc3_dz: f64 = 10.0, "RC3_DZ", "us", [0.0, 100.0], "RC channel 3: dead zone about its centre";
        /// Channel 4: pulse at its lowest.
        rc4_min: f64 = 1000.0, "RC4_MIN", "us", [800.0, 1500.0], "RC channel 4: pulse at its lowest (from the radio calibration)";
        /// Channel 4: pulse at its centre.
        rc4_trim: f64 = 1500.0, "RC4_TRIM", "us", [800.0, 2200.0], "RC channel 4: pulse at its centre";
        /// Channel 4: pulse at its highest.
        rc4_max: f64 = 2000.0, "RC4_MAX", "us", [1500.0, 2200.0], "RC channel 4: pulse at its highest";
        /// Channel 4: reversed (-1) or not (1).
        rc4_rev: f64 = 1.0, "RC4_REV", "", [-1.0, 1.0], "RC channel 4: 1 as is, -1 reversed";
        /// Channel 4: dead zone about its centre.
        rc4_dz: f64 = 10.0, "RC4_DZ", "us", [0.0, 100.0], "RC channel 4: dead zone about its centre";
        /// Channel 5: pulse at its lowest.
        rc5_min: f64 = 1000.0, "RC5_MIN", "us", [800.0, 1500.0], "RC channel 5: pulse at its lowest (from the radio calibration)";
        /// Channel 5: pulse at its centre.
        rc5_trim: f64 = 1500.0, "RC5_TRIM", "us", [800.0, 2200.0], "RC channel 5: pulse at its centre";
        /// Channel 5: pulse at its highest.
        rc5_max: f64 = 2000.0, "RC5_MAX", "us", [1500.0, 2200.0], "RC channel 5: pulse at its highest";
        /// Channel 5: reversed (-1) or not (1).
        rc5_rev: f64 = 1.0, "RC5_REV", "", [-1.0, 1.0], "RC channel 5: 1 as is, -1 reversed";
        /// Channel 5: dead zone about its centre.
        rc5_dz: f64 = 10.0, "RC5_DZ", "us", [0.0, 100.0], "RC channel 5: dead zone about its centre";
        /// Channel 6: pulse at its lowest.
        rc6_min: f64 = 1000.0, "RC6_MIN", "us", [800.0, 1500.0], "RC channel 6: pulse at its lowest (from the radio calibration)";
        /// Channel 6: pulse at its centre.
        rc6_trim: f64 = 1500.0, "RC6_TRIM", "us", [800.0, 2200.0], "RC channel 6: pulse at its centre";
        /// Channel 6: pulse at its highest.
        rc6_max: f64 = 2000.0, "RC6_MAX", "us", [1500.0, 2200.0], "RC channel 6: pulse at its highest";
        /// Channel 6: reversed (-1) or not (1).
        rc6_rev: f64 = 1.0, "RC6_REV", "", [-1.0, 1.0], "RC channel 6: 1 as is, -1 reversed";
        /// Channel 6: dead zone about its centre.
        rc6_dz: f64 = 10.0, "RC6_DZ", "us", [0.0, 100.0], "RC channel 6: dead zone about its centre";
        /// Channel 7: pulse at its lowest.
        rc7_min: f64 = 1000.0, "RC7_MIN", "us", [800.0, 1500.0], "RC channel 7: pulse at its lowest (from the radio calibration)";
        /// Channel 7: pulse at its centre.
        rc7_trim: f64 = 1500.0, "RC7_TRIM", "us", [800.0, 2200.0], "RC channel 7: pulse at its centre";
        /// Channel 7: pulse at its highest.
        rc7_max: f64 = 2000.0, "RC7_MAX", "us", [1500.0, 2200.0], "RC channel 7: pulse at its highest";
        /// Channel 7: reversed (-1) or not (1).
        rc7_rev: f64 = 1.0, "RC7_REV", "", [-1.0, 1.0], "RC channel 7: 1 as is, -1 reversed";
        /// Channel 7: dead zone about its centre.
        rc7_dz: f64 = 10.0, "RC7_DZ", "us", [0.0, 100.0], "RC channel 7: dead zone about its centre";
        /// Channel 8: pulse at its lowest.
        rc8_min: f64 = 1000.0, "RC8_MIN", "us", [800.0, 1500.0], "RC channel 8: pulse at its lowest (from the radio calibration)";
        /// Channel 8: pulse at its centre.
        rc8_trim: f64 = 1500.0, "RC8_TRIM", "us", [800.0, 2200.0], "RC channel 8: pulse at its centre";
        /// Channel 8: pulse at its highest.
        rc8_max: f64 = 2000.0, "RC8_MAX", "us", [1500.0, 2200.0], "RC channel 8: pulse at its highest";
        /// Channel 8: reversed (-1) or not (1).
        rc8_rev: f64 = 1.0, "RC8_REV", "", [-1.0, 1.0], "RC channel 8: 1 as is, -1 reversed";
        /// Channel 8: dead zone about its centre.
        rc8_dz: f64 = 10.0, "RC8_DZ", "us", [0.0, 100.0], "RC channel 8: dead zone about its centre";
        /// Channel 9: pulse at its lowest.
        rc9_min: f64 = 1000.0, "RC9_MIN", "us", [800.0, 1500.0], "RC channel 9: pulse at its lowest (from the radio calibration)";
        /// Channel 9: pulse at its centre.
        rc9_trim: f64 = 1500.0, "RC9_TRIM", "us", [800.0, 2200.0], "RC channel 9: pulse at its centre";
        /// Channel 9: pulse at its highest.
        rc9_max: f64 = 2000.0, "RC9_MAX", "us", [1500.0, 2200.0], "RC channel 9: pulse at its highest";
        /// Channel 9: reversed (-1) or not (1).
        rc9_rev: f64 = 1.0, "RC9_REV", "", [-1.0, 1.0], "RC channel 9: 1 as is, -1 reversed";
        /// Channel 9: dead zone about its centre.
        rc9_dz: f64 = 10.0, "RC9_DZ", "us", [0.0, 100.0], "RC channel 9: dead zone about its centre";
        /// Channel 10: pulse at its lowest.
        rc10_min: f64 = 1000.0, "RC10_MIN", "us", [800.0, 1500.0], "RC channel 10: pulse at its lowest (from the radio calibration)";
        /// Channel 10: pulse at its centre.
        rc10_trim: f64 = 1500.0, "RC10_TRIM", "us", [800.0, 2200.0], "RC channel 10: pulse at its centre";
        /// Channel 10: pulse at its highest.
        rc10_max: f64 = 2000.0, "RC10_MAX", "us", [1500.0, 2200.0], "RC channel 10: pulse at its highest";
        /// Channel 10: reversed (-1) or not (1).
        rc10_rev: f64 = 1.0, "RC10_REV", "", [-1.0, 1.0], "RC channel 10: 1 as is, -1 reversed";
        /// Channel 10: dead zone about its centre.
        rc10_dz: f64 = 10.0, "RC10_DZ", "us", [0.0, 100.0], "RC channel 10: dead zone about its centre";
        /// Channel 11: pulse at its lowest.
        rc11_min: f64 = 1000.0, "RC11_MIN", "us", [800.0, 1500.0], "RC channel 11: pulse at its lowest (from the radio calibration)";
        /// Channel 11: pulse at its centre.
        rc11_trim: f64 = 1500.0, "RC11_TRIM", "us", [800.0, 2200.0], "RC channel 11: pulse at its centre";
        /// Channel 11: pulse at its highest.
        rc11_max: f64 = 2000.0, "RC11_MAX", "us", [1500.0, 2200.0], "RC channel 11: pulse at its highest";
        /// Channel 11: reversed (-1) or not (1).
        rc11_rev: f64 = 1.0, "RC11_REV", "", [-1.0, 1.0], "RC channel 11: 1 as is, -1 reversed";
        /// Channel 11: dead zone about its centre.
        rc11_dz: f64 = 10.0, "RC11_DZ", "us", [0.0, 100.0], "RC channel 11: dead zone about its centre";
        /// Channel 12: pulse at its lowest.
        rc12_min: f64 = 1000.0, "RC12_MIN", "us", [800.0, 1500.0], "RC channel 12: pulse at its lowest (from the radio calibration)";
        /// Channel 12: pulse at its centre.
        rc12_trim: f64 = 1500.0, "RC12_TRIM", "us", [800.0, 2200.0], "RC channel 12: pulse at its centre";
        /// Channel 12: pulse at its highest.
        rc12_max: f64 = 2000.0, "RC12_MAX", "us", [1500.0, 2200.0], "RC channel 12: pulse at its highest";
        /// Channel 12: reversed (-1) or not (1).
        rc12_rev: f64 = 1.0, "RC12_REV", "", [-1.0, 1.0], "RC channel 12: 1 as is, -1 reversed";
        /// Channel 12: dead zone about its centre.
        rc12_dz: f64 = 10.0, "RC12_DZ", "us", [0.0, 100.0], "RC channel 12: dead zone about its centre";
        /// Channel 13: pulse at its lowest.
        rc13_min: f64 = 1000.0, "RC13_MIN", "us", [800.0, 1500.0], "RC channel 13: pulse at its lowest (from the radio calibration)";
        /// Channel 13: pulse at its centre.
        rc13_trim: f64 = 1500.0, "RC13_TRIM", "us", [800.0, 2200.0], "RC channel 13: pulse at its centre";
        /// Channel 13: pulse at its highest.
        rc13_max: f64 = 2000.0, "RC13_MAX", "us", [1500.0, 2200.0], "RC channel 13: pulse at its highest";
        /// Channel 13: reversed (-1) or not (1).
        rc13_rev: f64 = 1.0, "RC13_REV", "", [-1.0, 1.0], "RC channel 13: 1 as is, -1 reversed";
        /// Channel 13: dead zone about its centre.
        rc13_dz: f64 = 10.0, "RC13_DZ", "us", [0.0, 100.0], "RC channel 13: dead zone about its centre";
        /// Channel 14: pulse at its lowest.
        rc14_min: f64 = 1000.0, "RC14_MIN", "us", [800.0, 1500.0], "RC channel 14: pulse at its lowest (from the radio calibration)";
        /// Channel 14: pulse at its centre.
        rc14_trim: f64 = 1500.0, "RC14_TRIM", "us", [800.0, 2200.0], "RC channel 14: pulse at its centre";
        /// Channel 14: pulse at its highest.
        rc14_max: f64 = 2000.0, "RC14_MAX", "us", [1500.0, 2200.0], "RC channel 14: pulse at its highest";
        /// Channel 14: reversed (-1) or not (1).
        rc14_rev: f64 = 1.0, "RC14_REV", "", [-1.0, 1.0], "RC channel 14: 1 as is, -1 reversed";
        /// Channel 14: dead zone about its centre.
        rc14_dz: f64 = 10.0, "RC14_DZ", "us", [0.0, 100.0], "RC channel 14: dead zone about its centre";
        /// Channel 15: pulse at its lowest.
        rc15_min: f64 = 1000.0, "RC15_MIN", "us", [800.0, 1500.0], "RC channel 15: pulse at its lowest (from the radio calibration)";
        /// Channel 15: pulse at its centre.
        rc15_trim: f64 = 1500.0, "RC15_TRIM", "us", [800.0, 2200.0], "RC channel 15: pulse at its centre";
        /// Channel 15: pulse at its highest.
        rc15_max: f64 = 2000.0, "RC15_MAX", "us", [1500.0, 2200.0], "RC channel 15: pulse at its highest";
        /// Channel 15: reversed (-1) or not (1).
        rc15_rev: f64 = 1.0, "RC15_REV", "", [-1.0, 1.0], "RC channel 15: 1 as is, -1 reversed";
        /// Channel 15: dead zone about its centre.
        rc15_dz: f64 = 10.0, "RC15_DZ", "us", [0.0, 100.0], "RC channel 15: dead zone about its centre";
        /// Channel 16: pulse at its lowest.
        rc16_min: f64 = 1000.0, "RC16_MIN", "us", [800.0, 1500.0], "RC channel 16: pulse at its lowest (from the radio calibration)";
        /// Channel 16: pulse at its centre.
        rc16_trim: f64 = 1500.0, "RC16_TRIM", "us", [800.0, 2200.0], "RC channel 16: pulse at its centre";
        /// Channel 16: pulse at its highest.
        rc16_max: f64 = 2000.0, "RC16_MAX", "us", [1500.0, 2200.0], "RC channel 16: pulse at its highest";
        /// Channel 16: reversed (-1) or not (1).
        rc16_rev: f64 = 1.0, "RC16_REV", "", [-1.0, 1.0], "RC channel 16: 1 as is, -1 reversed";
        /// Channel 16: dead zone about its centre.
        rc16_dz: f64 = 10.0, "RC16_DZ", "us", [0.0, 100.0], "RC channel 16: dead zone about its centre";
    }
}
