//! What a u-blox receiver is told at start, built with the `ublox` crate's builders: the baud
//! switch, then UBX output only, `NAV-PVT` and `NAV-DOP` on every epoch, and the navigation
//! rate. Generation 9 and later (protocol 27 on: M9, M10, F9P) take it as one `CFG-VALSET`
//! in RAM; older receivers (M8) as `CFG-PRT`, `CFG-RATE` and `CFG-MSG`, as PX4's and
//! ArduPilot's drivers do.

use ublox::UbxPacketMeta;
use ublox::cfg_val::CfgVal;
use ublox::packets::cfg_msg::{CfgMsgSinglePort, CfgMsgSinglePortBuilder};
use ublox::packets::cfg_prt::{
    CfgPrtUart, CfgPrtUartBuilder, DataBits, InProtoMask, OutProtoMask, Parity, StopBits, UartMode,
    UartPortId,
};
use ublox::packets::cfg_rate::{AlignmentToReferenceTime, CfgRate, CfgRateBuilder};
use ublox::packets::cfg_val::{CfgLayerSet, CfgValSet, CfgValSetBuilder};
use ublox::packets::nav_dop::NavDop;
use ublox::packets::nav_pvt::proto23::NavPvt;

/// The first protocol version with the configuration interface of generation 9
/// (`CFG-VALSET`/`CFG-VALGET`); earlier ones have only the legacy `CFG-*` messages.
pub const VALSET_PROTOCOL: f64 = 27.0;

/// One configuration message: its name, its bytes, and the (class, id) its `ACK-ACK` names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigMessage {
    /// The message's name, for what the driver says.
    pub name: &'static str,
    /// The whole UBX frame.
    pub bytes: Vec<u8>,
    /// Class and id acknowledged.
    pub acked_as: (u8, u8),
}

/// The two configuration interfaces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interface {
    /// `CFG-VALSET` (protocol 27 on).
    Valset,
    /// `CFG-PRT`, `CFG-RATE`, `CFG-MSG`.
    Legacy,
}

impl Interface {
    /// The interface a receiver of protocol version `protocol` takes (legacy when unknown).
    pub fn for_protocol(protocol: Option<f64>) -> Self {
        match protocol {
            Some(p) if p >= VALSET_PROTOCOL => Self::Valset,
            _ => Self::Legacy,
        }
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Valset => "CFG-VALSET",
            Self::Legacy => "CFG-PRT/CFG-RATE/CFG-MSG",
        }
    }
}

fn valset(name: &'static str, items: &[CfgVal]) -> ConfigMessage {
    let mut bytes = Vec::new();
    CfgValSetBuilder {
        version: 0,
        layers: CfgLayerSet::RAM,
        reserved1: 0,
        cfg_data: items,
    }
    .extend_to(&mut bytes);
    ConfigMessage {
        name,
        bytes,
        acked_as: (CfgValSet::CLASS, CfgValSet::ID),
    }
}

fn prt(baud: u32) -> ConfigMessage {
    let bytes = CfgPrtUartBuilder {
        portid: UartPortId::Uart1,
        reserved0: 0,
        tx_ready: 0,
        mode: UartMode::new(DataBits::Eight, Parity::None, StopBits::One),
        baud_rate: baud,
        in_proto_mask: InProtoMask::UBLOX | InProtoMask::NMEA,
        out_proto_mask: OutProtoMask::UBLOX,
        flags: 0,
        reserved5: 0,
    }
    .into_packet_bytes()
    .to_vec();
    ConfigMessage {
        name: "CFG-PRT",
        bytes,
        acked_as: (CfgPrtUart::CLASS, CfgPrtUart::ID),
    }
}

/// The message that moves the receiver's UART1 to `baud` (and to UBX output).
pub fn baud_switch(interface: Interface, baud: u32) -> ConfigMessage {
    match interface {
        Interface::Valset => valset("CFG-VALSET (baud)", &[CfgVal::Uart1Baudrate(baud)]),
        Interface::Legacy => prt(baud),
    }
}

/// The configuration at the final baud: UBX out only, `NAV-PVT` and `NAV-DOP` every epoch,
/// a measurement every `period_ms`. The legacy `CFG-MSG` of three bytes sets the rate on the
/// port it arrives on, whichever that is; `CFG-VALSET` names UART1 and USB both.
pub fn messages(interface: Interface, baud: u32, period_ms: u16) -> Vec<ConfigMessage> {
    match interface {
        // UART1 and USB alike: the driver cannot tell which of them it is on (a receiver on a
        // USB cable is as common as one on a UART), as PX4 configures both.
        Interface::Valset => vec![valset(
            "CFG-VALSET",
            &[
                CfgVal::Uart1InProtUbx(true),
                CfgVal::Uart1OutProtUbx(true),
                CfgVal::Uart1OutProtNmea(false),
                CfgVal::MsgOutUbxNavPvtUart1(1),
                CfgVal::MsgOutUbxNavDopUart1(1),
                CfgVal::UsbInProtUbx(true),
                CfgVal::UsbOutProtUbx(true),
                CfgVal::UsbOutProtNmea(false),
                CfgVal::MsgOutUbxNavPvtUsb(1),
                CfgVal::MsgOutUbxNavDopUsb(1),
                CfgVal::RateMeas(period_ms),
                CfgVal::RateNav(1),
            ],
        )],
        Interface::Legacy => {
            let msg = |name, bytes: [u8; 11]| ConfigMessage {
                name,
                bytes: bytes.to_vec(),
                acked_as: (CfgMsgSinglePort::CLASS, CfgMsgSinglePort::ID),
            };
            let rate = CfgRateBuilder {
                measure_rate_ms: period_ms,
                nav_rate: 1,
                time_ref: AlignmentToReferenceTime::Gps,
            }
            .into_packet_bytes()
            .to_vec();
            vec![
                prt(baud),
                ConfigMessage {
                    name: "CFG-RATE",
                    bytes: rate,
                    acked_as: (CfgRate::CLASS, CfgRate::ID),
                },
                msg(
                    "CFG-MSG (NAV-PVT)",
                    CfgMsgSinglePortBuilder::set_rate_for::<NavPvt>(1).into_packet_bytes(),
                ),
                msg(
                    "CFG-MSG (NAV-DOP)",
                    CfgMsgSinglePortBuilder::set_rate_for::<NavDop>(1).into_packet_bytes(),
                ),
            ]
        }
    }
}
