//! The Opal Kelly XEM6310 top: the pins, the FrontPanel host interface and
//! its endpoints, the DDR2 controller (or its parked pins) and the sensor
//! port, around the core ([`crate::xem6310_core`]: the register map, the
//! pipeline, the replay and mask pipes and the packet pipe-out).
//!
//! **Black boxes.** Opal Kelly's FrontPanel HDL (okHost, okWireIn, okWireOut,
//! okTriggerIn, okBTPipeIn, okBTPipeOut, okWireOR) and the Xilinx MIG DDR2
//! controller are proprietary or generated netlists, never a dependency:
//! [`OkHost`], [`OkEndpoint`], [`OkWireOr`] … ([`crate::frontpanel`]) and
//! [`MigDdr2`] ([`crate::mig_ddr2`]) instantiate them by name, and the
//! generated Verilog carries `(* blackbox *)` declarations of their ports
//! (written from Opal Kelly's public FrontPanel user's manual and Xilinx
//! UG388; stub bodies only drive outputs to 0 so that Verilator can lint the
//! design). To build a bitfile, add Opal Kelly's `okLibrary.v` and the `.ngc`
//! cores for the XEM6310, and the MIG-generated DDR2 controller named
//! `smartagg_mig` (configured as [`crate::mig_ddr2`] says); the declarations
//! must then be left out. The designs whose delay line is on chip park the
//! DDR2 pins instead ([`ParkedDdr2`]).
//!
//! **Clock.** Everything but the sensor port runs on the host-interface
//! clock `okClk` (100.8 MHz, period 9.92 ns); the MCB user port is clocked
//! by it too (its FIFOs cross into the memory clock).
//!
//! **Sensor port** (placeholder: the SPCImager's connector pin-out is not
//! published). `sensor_clk`, `sensor_valid`, `sensor_sop` and P data bits on
//! expansion connector JP2, 3.3 V LVCMOS (see `constraints/xem6310.ucf`);
//! the words cross into `okClk` through an asynchronous FIFO whose overflow
//! is a sticky status bit.

use crate::config::{BackHalfConfig, GatewareError};
use crate::frontpanel::{EndpointKind, OkEndpoint, OkHost, OkWireOr};
use crate::mig_ddr2::{MigDdr2, ParkedDdr2};
use crate::registers;
use crate::xem6310_core::{XemCore, XemCoreOnChip};
use rust_hdl::prelude::*;

/// Depth (address bits) of the sensor port's clock-crossing FIFO.
pub const SENSOR_FIFO_BITS: usize = 5;

/// Declares an XEM6310 top ([`Xem6310Top`], [`Xem6310TopOnChip`]) around a
/// core type ([`XemCore`], [`XemCoreOnChip`]) and a DDR2 block ([`MigDdr2`],
/// [`ParkedDdr2`]): the same pins, endpoints and sensor port, so one
/// `constraints/xem6310.ucf` places both.
macro_rules! xem_top {
    ($(#[$attr:meta])* $top:ident, $core:ident, $mem:ident) => {
$(#[$attr])*
#[allow(non_snake_case)]
#[derive(LogicBlock)]
pub struct $top<
    const P: usize,
    const PAW: usize,
    const CW: usize,
    const CAW: usize,
    const VW: usize,
    const HW: usize,
    const LAW: usize,
    const RAW: usize,
    const RCW: usize,
    const CAW2: usize,
    const BW: usize,
    const QAW: usize,
    const QW: usize,
    const PW: usize,
    const TW: usize,
    const TAW: usize,
    const OAW: usize,
> {
    /// FrontPanel host interface.
    pub okUH: Signal<In, Bits<5>>,
    /// FrontPanel host interface.
    pub okHU: Signal<Out, Bits<3>>,
    /// FrontPanel host interface.
    pub okUHU: Signal<InOut, Bits<32>>,
    /// FrontPanel host interface.
    pub okAA: Signal<InOut, Bit>,
    /// 100 MHz system clock (LVDS), for the MIG.
    pub sys_clkp: Signal<In, Bit>,
    /// 100 MHz system clock (LVDS), for the MIG.
    pub sys_clkn: Signal<In, Bit>,
    /// LEDs, active low: running, ended, overflowed, config error, fault, memory ready.
    pub led: Signal<Out, Bits<8>>,
    /// DDR2 data.
    pub ddr2_dq: Signal<InOut, Bits<16>>,
    /// DDR2 address.
    pub ddr2_a: Signal<Out, Bits<13>>,
    /// DDR2 bank.
    pub ddr2_ba: Signal<Out, Bits<3>>,
    /// DDR2 RAS#.
    pub ddr2_ras_n: Signal<Out, Bit>,
    /// DDR2 CAS#.
    pub ddr2_cas_n: Signal<Out, Bit>,
    /// DDR2 WE#.
    pub ddr2_we_n: Signal<Out, Bit>,
    /// DDR2 ODT.
    pub ddr2_odt: Signal<Out, Bit>,
    /// DDR2 CKE.
    pub ddr2_cke: Signal<Out, Bit>,
    /// DDR2 lower data mask.
    pub ddr2_dm: Signal<Out, Bit>,
    /// DDR2 upper data mask.
    pub ddr2_udm: Signal<Out, Bit>,
    /// DDR2 lower strobe.
    pub ddr2_dqs: Signal<InOut, Bit>,
    /// DDR2 lower strobe, negative.
    pub ddr2_dqs_n: Signal<InOut, Bit>,
    /// DDR2 upper strobe.
    pub ddr2_udqs: Signal<InOut, Bit>,
    /// DDR2 upper strobe, negative.
    pub ddr2_udqs_n: Signal<InOut, Bit>,
    /// DDR2 clock.
    pub ddr2_ck: Signal<Out, Bit>,
    /// DDR2 clock, negative.
    pub ddr2_ck_n: Signal<Out, Bit>,
    /// DDR2 chip select (held low).
    pub ddr2_cs_n: Signal<Out, Bit>,
    /// MCB calibration resistor.
    pub ddr2_rzq: Signal<InOut, Bit>,
    /// MCB calibration pin.
    pub ddr2_zio: Signal<InOut, Bit>,
    /// Sensor port (placeholder pins): word clock.
    pub sensor_clk: Signal<In, Clock>,
    /// Sensor port: a word this clock.
    pub sensor_valid: Signal<In, Bit>,
    /// Sensor port: first word of a plane.
    pub sensor_sop: Signal<In, Bit>,
    /// Sensor port: P pixels.
    pub sensor_data: Signal<In, Bits<P>>,
    host: OkHost,
    wire_or: OkWireOr<715>,
    wi0: OkEndpoint,
    wi1: OkEndpoint,
    wi2: OkEndpoint,
    wi3: OkEndpoint,
    wi4: OkEndpoint,
    wi5: OkEndpoint,
    wi6: OkEndpoint,
    wi7: OkEndpoint,
    wi8: OkEndpoint,
    wo0: OkEndpoint,
    wo1: OkEndpoint,
    wo2: OkEndpoint,
    wo3: OkEndpoint,
    wo4: OkEndpoint,
    wo5: OkEndpoint,
    wo6: OkEndpoint,
    wo7: OkEndpoint,
    ti40: OkEndpoint,
    pi80: OkEndpoint,
    pi81: OkEndpoint,
    poa0: OkEndpoint,
    mig: $mem,
    sensor_fifo: AsynchronousFIFO<Bits<32>, SENSOR_FIFO_BITS, 6, 1>,
    sensor_sync: BitSynchronizer,
    core: $core<P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>,
    sop_shift: Constant<Bits<8>>,
}

impl<
        const P: usize,
        const PAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > $top<P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    /// The top of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        use registers::{pipe, trigger, wire_in, wire_out};
        use EndpointKind::*;
        let wi = |a: u8| OkEndpoint::new(WireIn, wire_in::CONTROL + a);
        let wo = |a: u8| OkEndpoint::new(WireOut, wire_out::STATUS + a);
        Ok($top {
            okUH: Default::default(),
            okHU: Default::default(),
            okUHU: Default::default(),
            okAA: Default::default(),
            sys_clkp: Default::default(),
            sys_clkn: Default::default(),
            led: Default::default(),
            ddr2_dq: Default::default(),
            ddr2_a: Default::default(),
            ddr2_ba: Default::default(),
            ddr2_ras_n: Default::default(),
            ddr2_cas_n: Default::default(),
            ddr2_we_n: Default::default(),
            ddr2_odt: Default::default(),
            ddr2_cke: Default::default(),
            ddr2_dm: Default::default(),
            ddr2_udm: Default::default(),
            ddr2_dqs: Default::default(),
            ddr2_dqs_n: Default::default(),
            ddr2_udqs: Default::default(),
            ddr2_udqs_n: Default::default(),
            ddr2_ck: Default::default(),
            ddr2_ck_n: Default::default(),
            ddr2_cs_n: Default::default(),
            ddr2_rzq: Default::default(),
            ddr2_zio: Default::default(),
            sensor_clk: Default::default(),
            sensor_valid: Default::default(),
            sensor_sop: Default::default(),
            sensor_data: Default::default(),
            host: Default::default(),
            wire_or: Default::default(),
            wi0: wi(0),
            wi1: wi(1),
            wi2: wi(2),
            wi3: wi(3),
            wi4: wi(4),
            wi5: wi(5),
            wi6: wi(6),
            wi7: wi(7),
            wi8: wi(8),
            wo0: wo(0),
            wo1: wo(1),
            wo2: wo(2),
            wo3: wo(3),
            wo4: wo(4),
            wo5: wo(5),
            wo6: wo(6),
            wo7: wo(7),
            ti40: OkEndpoint::new(TriggerIn, trigger::CONTROL),
            pi80: OkEndpoint::new(BtPipeIn, pipe::REPLAY_IN),
            pi81: OkEndpoint::new(BtPipeIn, pipe::MASK_IN),
            poa0: OkEndpoint::new(BtPipeOut, pipe::STREAM_OUT),
            mig: Default::default(),
            sensor_fifo: Default::default(),
            sensor_sync: Default::default(),
            core: $core::new(cfg)?,
            sop_shift: Constant::new((P as u64).to_bits()),
        })
    }
}

impl<
        const P: usize,
        const PAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > Logic
    for $top<P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    #[hdl_gen]
    fn update(&mut self) {
        // Host interface and its clock.
        self.host.ok_uh.next = self.okUH.val();
        self.okHU.next = self.host.ok_hu.val();
        Signal::<InOut, Bits<32>>::link(&mut self.okUHU, &mut self.host.ok_uhu);
        Signal::<InOut, Bit>::link(&mut self.okAA, &mut self.host.ok_aa);
        self.host.ok_eh.next = self.wire_or.ok_eh.val();
        self.core.clock.next = self.host.ok_clk.val();
        self.ti40.ep_clk.next = self.host.ok_clk.val();
        self.wi0.ok_he.next = self.host.ok_he.val();
        self.wi1.ok_he.next = self.host.ok_he.val();
        self.wi2.ok_he.next = self.host.ok_he.val();
        self.wi3.ok_he.next = self.host.ok_he.val();
        self.wi4.ok_he.next = self.host.ok_he.val();
        self.wi5.ok_he.next = self.host.ok_he.val();
        self.wi6.ok_he.next = self.host.ok_he.val();
        self.wi7.ok_he.next = self.host.ok_he.val();
        self.wi8.ok_he.next = self.host.ok_he.val();
        self.wo0.ok_he.next = self.host.ok_he.val();
        self.wo1.ok_he.next = self.host.ok_he.val();
        self.wo2.ok_he.next = self.host.ok_he.val();
        self.wo3.ok_he.next = self.host.ok_he.val();
        self.wo4.ok_he.next = self.host.ok_he.val();
        self.wo5.ok_he.next = self.host.ok_he.val();
        self.wo6.ok_he.next = self.host.ok_he.val();
        self.wo7.ok_he.next = self.host.ok_he.val();
        self.ti40.ok_he.next = self.host.ok_he.val();
        self.pi80.ok_he.next = self.host.ok_he.val();
        self.pi81.ok_he.next = self.host.ok_he.val();
        self.poa0.ok_he.next = self.host.ok_he.val();
        // The endpoints that answer the host, one 65-bit bus each.
        self.wire_or.ok_ehx.next = bit_cast::<715, 65>(self.wo0.ok_eh.val())
            | (bit_cast::<715, 65>(self.wo1.ok_eh.val()) << 65)
            | (bit_cast::<715, 65>(self.wo2.ok_eh.val()) << 130)
            | (bit_cast::<715, 65>(self.wo3.ok_eh.val()) << 195)
            | (bit_cast::<715, 65>(self.wo4.ok_eh.val()) << 260)
            | (bit_cast::<715, 65>(self.wo5.ok_eh.val()) << 325)
            | (bit_cast::<715, 65>(self.wo6.ok_eh.val()) << 390)
            | (bit_cast::<715, 65>(self.wo7.ok_eh.val()) << 455)
            | (bit_cast::<715, 65>(self.pi80.ok_eh.val()) << 520)
            | (bit_cast::<715, 65>(self.pi81.ok_eh.val()) << 585)
            | (bit_cast::<715, 65>(self.poa0.ok_eh.val()) << 650);
        // Unused endpoint inputs.
        self.wi0.ep_datain.next = 0.into();
        self.wi1.ep_datain.next = 0.into();
        self.wi2.ep_datain.next = 0.into();
        self.wi3.ep_datain.next = 0.into();
        self.wi4.ep_datain.next = 0.into();
        self.wi5.ep_datain.next = 0.into();
        self.wi6.ep_datain.next = 0.into();
        self.wi7.ep_datain.next = 0.into();
        self.wi8.ep_datain.next = 0.into();
        self.ti40.ep_datain.next = 0.into();
        self.pi80.ep_datain.next = 0.into();
        self.pi81.ep_datain.next = 0.into();
        self.wi0.ep_ready.next = false;
        self.wi1.ep_ready.next = false;
        self.wi2.ep_ready.next = false;
        self.wi3.ep_ready.next = false;
        self.wi4.ep_ready.next = false;
        self.wi5.ep_ready.next = false;
        self.wi6.ep_ready.next = false;
        self.wi7.ep_ready.next = false;
        self.wi8.ep_ready.next = false;
        self.wo0.ep_ready.next = false;
        self.wo1.ep_ready.next = false;
        self.wo2.ep_ready.next = false;
        self.wo3.ep_ready.next = false;
        self.wo4.ep_ready.next = false;
        self.wo5.ep_ready.next = false;
        self.wo6.ep_ready.next = false;
        self.wo7.ep_ready.next = false;
        self.ti40.ep_ready.next = false;
        self.wi0.ep_clk.next = self.host.ok_clk.val();
        self.wi1.ep_clk.next = self.host.ok_clk.val();
        self.wi2.ep_clk.next = self.host.ok_clk.val();
        self.wi3.ep_clk.next = self.host.ok_clk.val();
        self.wi4.ep_clk.next = self.host.ok_clk.val();
        self.wi5.ep_clk.next = self.host.ok_clk.val();
        self.wi6.ep_clk.next = self.host.ok_clk.val();
        self.wi7.ep_clk.next = self.host.ok_clk.val();
        self.wi8.ep_clk.next = self.host.ok_clk.val();
        self.wo0.ep_clk.next = self.host.ok_clk.val();
        self.wo1.ep_clk.next = self.host.ok_clk.val();
        self.wo2.ep_clk.next = self.host.ok_clk.val();
        self.wo3.ep_clk.next = self.host.ok_clk.val();
        self.wo4.ep_clk.next = self.host.ok_clk.val();
        self.wo5.ep_clk.next = self.host.ok_clk.val();
        self.wo6.ep_clk.next = self.host.ok_clk.val();
        self.wo7.ep_clk.next = self.host.ok_clk.val();
        self.pi80.ep_clk.next = self.host.ok_clk.val();
        self.pi81.ep_clk.next = self.host.ok_clk.val();
        self.poa0.ep_clk.next = self.host.ok_clk.val();

        // Registers, triggers, pipes.
        self.core.wire_in[0].next = self.wi0.ep_dataout.val();
        self.core.wire_in[1].next = self.wi1.ep_dataout.val();
        self.core.wire_in[2].next = self.wi2.ep_dataout.val();
        self.core.wire_in[3].next = self.wi3.ep_dataout.val();
        self.core.wire_in[4].next = self.wi4.ep_dataout.val();
        self.core.wire_in[5].next = self.wi5.ep_dataout.val();
        self.core.wire_in[6].next = self.wi6.ep_dataout.val();
        self.core.wire_in[7].next = self.wi7.ep_dataout.val();
        self.core.wire_in[8].next = self.wi8.ep_dataout.val();
        self.core.trigger.next = self.ti40.ep_dataout.val();
        self.wo0.ep_datain.next = self.core.wire_out[0].val();
        self.wo1.ep_datain.next = self.core.wire_out[1].val();
        self.wo2.ep_datain.next = self.core.wire_out[2].val();
        self.wo3.ep_datain.next = self.core.wire_out[3].val();
        self.wo4.ep_datain.next = self.core.wire_out[4].val();
        self.wo5.ep_datain.next = self.core.wire_out[5].val();
        self.wo6.ep_datain.next = self.core.wire_out[6].val();
        self.wo7.ep_datain.next = self.core.wire_out[7].val();
        self.core.replay_write.next = self.pi80.ep_strobe.val();
        self.core.replay_data.next = self.pi80.ep_dataout.val();
        self.pi80.ep_ready.next = self.core.replay_ready.val();
        self.core.mask_write.next = self.pi81.ep_strobe.val();
        self.core.mask_data.next = self.pi81.ep_dataout.val();
        self.pi81.ep_ready.next = self.core.mask_ready.val();
        self.core.out_read.next = self.poa0.ep_strobe.val();
        self.poa0.ep_datain.next = self.core.out_data.val();
        self.poa0.ep_ready.next = self.core.out_ready.val();

        // Sensor port: into okClk through the asynchronous FIFO.
        self.sensor_fifo.write_clock.next = self.sensor_clk.val();
        self.sensor_fifo.read_clock.next = self.host.ok_clk.val();
        self.sensor_fifo.write.next = self.sensor_valid.val() & !self.sensor_fifo.full.val();
        self.sensor_fifo.data_in.next = bit_cast::<32, P>(self.sensor_data.val())
            | (bit_cast::<32, 1>(self.sensor_sop.val().into()) << self.sop_shift.val());
        self.sensor_fifo.read.next = self.core.sensor_read.val();
        self.core.sensor_empty.next = self.sensor_fifo.empty.val();
        self.core.sensor_word.next = self.sensor_fifo.data_out.val();
        self.sensor_sync.clock.next = self.host.ok_clk.val();
        self.sensor_sync.sig_in.next = self.sensor_fifo.overflow.val();
        self.core.sensor_overflow.next = self.sensor_sync.sig_out.val();

        // DDR2 through the MIG.
        self.mig.sys_clk_p.next = self.sys_clkp.val();
        self.mig.sys_clk_n.next = self.sys_clkn.val();
        self.mig.sys_rst.next = false;
        self.mig.port_clk.next = self.host.ok_clk.val();
        self.core.mcb.calib_done.next = self.mig.mcb.calib_done.val();
        self.mig.mcb.cmd_en.next = self.core.mcb.cmd_en.val();
        self.mig.mcb.cmd_instr.next = self.core.mcb.cmd_instr.val();
        self.mig.mcb.cmd_bl.next = self.core.mcb.cmd_bl.val();
        self.mig.mcb.cmd_addr.next = self.core.mcb.cmd_addr.val();
        self.core.mcb.cmd_full.next = self.mig.mcb.cmd_full.val();
        self.mig.mcb.wr_en.next = self.core.mcb.wr_en.val();
        self.mig.mcb.wr_mask.next = self.core.mcb.wr_mask.val();
        self.mig.mcb.wr_data.next = self.core.mcb.wr_data.val();
        self.core.mcb.wr_full.next = self.mig.mcb.wr_full.val();
        self.mig.mcb.rd_en.next = self.core.mcb.rd_en.val();
        self.core.mcb.rd_data.next = self.mig.mcb.rd_data.val();
        self.core.mcb.rd_empty.next = self.mig.mcb.rd_empty.val();
        Signal::<InOut, Bits<16>>::link(&mut self.ddr2_dq, &mut self.mig.dq);
        Signal::<InOut, Bit>::link(&mut self.ddr2_dqs, &mut self.mig.dqs);
        Signal::<InOut, Bit>::link(&mut self.ddr2_dqs_n, &mut self.mig.dqs_n);
        Signal::<InOut, Bit>::link(&mut self.ddr2_udqs, &mut self.mig.udqs);
        Signal::<InOut, Bit>::link(&mut self.ddr2_udqs_n, &mut self.mig.udqs_n);
        Signal::<InOut, Bit>::link(&mut self.ddr2_rzq, &mut self.mig.rzq);
        Signal::<InOut, Bit>::link(&mut self.ddr2_zio, &mut self.mig.zio);
        self.ddr2_a.next = self.mig.a.val();
        self.ddr2_ba.next = self.mig.ba.val();
        self.ddr2_ras_n.next = self.mig.ras_n.val();
        self.ddr2_cas_n.next = self.mig.cas_n.val();
        self.ddr2_we_n.next = self.mig.we_n.val();
        self.ddr2_odt.next = self.mig.odt.val();
        self.ddr2_cke.next = self.mig.cke.val();
        self.ddr2_dm.next = self.mig.dm.val();
        self.ddr2_udm.next = self.mig.udm.val();
        self.ddr2_ck.next = self.mig.ck.val();
        self.ddr2_ck_n.next = self.mig.ck_n.val();
        self.ddr2_cs_n.next = false;

        // LEDs (active low): the status bits 0..5.
        self.led.next = !self.core.wire_out[0].val().get_bits::<8>(0);
    }
}

    };
}

xem_top!(
    /// The XEM6310 top: pins, FrontPanel endpoints, MIG, sensor port, core.
    /// Port names are the pin names of `constraints/xem6310.ucf`.
    Xem6310Top,
    XemCore,
    MigDdr2
);

xem_top!(
    /// The XEM6310 top of a design whose delay line is on chip (block RAM):
    /// [`Xem6310Top`]'s pins and endpoints around [`XemCoreOnChip`], with
    /// the DDR2 parked ([`ParkedDdr2`]). Port names are the pin names of
    /// `constraints/xem6310.ucf`.
    Xem6310TopOnChip,
    XemCoreOnChip,
    ParkedDdr2
);
