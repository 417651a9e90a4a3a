//! The XEM6310's DDR2 as blocks with the DDR2 pins and the MCB user port:
//! [`MigDdr2`], the Xilinx MIG DDR2 controller as a black box, and
//! [`ParkedDdr2`], the same ports with the pins parked and no controller,
//! for the designs whose delay line is on chip (block RAM). The MIG core is
//! a generated netlist, never a dependency: [`MigDdr2`] instantiates it by
//! name (`smartagg_mig`), and the generated Verilog carries a
//! `(* blackbox *)` declaration of its ports written from Xilinx UG388 (the
//! stub body only drives outputs to 0, so that Verilator can lint the
//! design). To build a bitfile, add the MIG-generated DDR2 controller named
//! `smartagg_mig` (Spartan-6 MCB3, DDR2 MT47H64M16, 16 bits, one 32-bit
//! bidirectional user port p0, differential 100 MHz system clock,
//! `c3_sys_rst_i` active high) and leave the declaration out. A part of the
//! XEM6310 top ([`crate::xem6310`]); in simulation the MCB user port is
//! served by the behavioural MCB ([`crate::testbench::mcb_model`]).

use crate::bundles::McbMemory;
use rust_hdl::prelude::*;

/// Port declaration of the MIG-generated DDR2 controller (black box).
const MIG_DECLARATION: &str = r#"
(* blackbox *)
module smartagg_mig(
    inout wire [15:0] mcb3_dram_dq, output wire [12:0] mcb3_dram_a, output wire [2:0] mcb3_dram_ba,
    output wire mcb3_dram_ras_n, output wire mcb3_dram_cas_n, output wire mcb3_dram_we_n,
    output wire mcb3_dram_odt, output wire mcb3_dram_cke, output wire mcb3_dram_dm,
    inout wire mcb3_dram_udqs, inout wire mcb3_dram_udqs_n, inout wire mcb3_rzq,
    inout wire mcb3_zio, output wire mcb3_dram_udm, inout wire mcb3_dram_dqs,
    inout wire mcb3_dram_dqs_n, output wire mcb3_dram_ck, output wire mcb3_dram_ck_n,
    input wire c3_sys_clk_p, input wire c3_sys_clk_n, input wire c3_sys_rst_i,
    output wire c3_calib_done, output wire c3_clk0, output wire c3_rst0,
    input wire c3_p0_cmd_clk, input wire c3_p0_cmd_en, input wire [2:0] c3_p0_cmd_instr,
    input wire [5:0] c3_p0_cmd_bl, input wire [29:0] c3_p0_cmd_byte_addr,
    output wire c3_p0_cmd_empty, output wire c3_p0_cmd_full,
    input wire c3_p0_wr_clk, input wire c3_p0_wr_en, input wire [3:0] c3_p0_wr_mask,
    input wire [31:0] c3_p0_wr_data, output wire c3_p0_wr_full, output wire c3_p0_wr_empty,
    output wire [6:0] c3_p0_wr_count, output wire c3_p0_wr_underrun, output wire c3_p0_wr_error,
    input wire c3_p0_rd_clk, input wire c3_p0_rd_en, output wire [31:0] c3_p0_rd_data,
    output wire c3_p0_rd_full, output wire c3_p0_rd_empty, output wire [6:0] c3_p0_rd_count,
    output wire c3_p0_rd_overflow, output wire c3_p0_rd_error);
assign {mcb3_dram_a, mcb3_dram_ba, mcb3_dram_ras_n, mcb3_dram_cas_n, mcb3_dram_we_n} = 19'h0;
assign {mcb3_dram_odt, mcb3_dram_cke, mcb3_dram_dm, mcb3_dram_udm, mcb3_dram_ck, mcb3_dram_ck_n} = 6'h0;
assign {c3_calib_done, c3_clk0, c3_rst0, c3_p0_cmd_empty, c3_p0_cmd_full} = 5'h0;
assign {c3_p0_wr_full, c3_p0_wr_empty, c3_p0_wr_count, c3_p0_wr_underrun, c3_p0_wr_error} = 11'h0;
assign {c3_p0_rd_data, c3_p0_rd_full, c3_p0_rd_empty, c3_p0_rd_count} = 41'h0;
assign {c3_p0_rd_overflow, c3_p0_rd_error} = 2'h0;
endmodule
"#;

/// Declares a block with the DDR2 pins and the MCB user port ([`MigDdr2`],
/// [`ParkedDdr2`]) whose Verilog is `$code` (an instance) with the modules
/// of `$cores`.
macro_rules! ddr2_port {
    ($(#[$attr:meta])* $name:ident, $code:expr, $cores:expr) => {
$(#[$attr])*
#[derive(LogicBlock, Default)]
pub struct $name {
    /// 100 MHz system clock, LVDS positive.
    pub sys_clk_p: Signal<In, Bit>,
    /// 100 MHz system clock, LVDS negative.
    pub sys_clk_n: Signal<In, Bit>,
    /// Reset, active high.
    pub sys_rst: Signal<In, Bit>,
    /// User-port clock (okClk).
    pub port_clk: Signal<In, Clock>,
    /// The user port (clocked by `port_clk`).
    pub mcb: McbMemory,
    /// DDR2 data.
    pub dq: Signal<InOut, Bits<16>>,
    /// DDR2 address.
    pub a: Signal<Out, Bits<13>>,
    /// DDR2 bank.
    pub ba: Signal<Out, Bits<3>>,
    /// DDR2 RAS#.
    pub ras_n: Signal<Out, Bit>,
    /// DDR2 CAS#.
    pub cas_n: Signal<Out, Bit>,
    /// DDR2 WE#.
    pub we_n: Signal<Out, Bit>,
    /// DDR2 ODT.
    pub odt: Signal<Out, Bit>,
    /// DDR2 CKE.
    pub cke: Signal<Out, Bit>,
    /// DDR2 lower data mask.
    pub dm: Signal<Out, Bit>,
    /// DDR2 upper data mask.
    pub udm: Signal<Out, Bit>,
    /// DDR2 lower strobe.
    pub dqs: Signal<InOut, Bit>,
    /// DDR2 lower strobe, negative.
    pub dqs_n: Signal<InOut, Bit>,
    /// DDR2 upper strobe.
    pub udqs: Signal<InOut, Bit>,
    /// DDR2 upper strobe, negative.
    pub udqs_n: Signal<InOut, Bit>,
    /// DDR2 clock.
    pub ck: Signal<Out, Bit>,
    /// DDR2 clock, negative.
    pub ck_n: Signal<Out, Bit>,
    /// MCB calibration resistor.
    pub rzq: Signal<InOut, Bit>,
    /// MCB calibration pin.
    pub zio: Signal<InOut, Bit>,
}

impl Logic for $name {
    fn update(&mut self) {}
    fn connect(&mut self) {
        self.mcb.calib_done.connect();
        self.mcb.cmd_full.connect();
        self.mcb.wr_full.connect();
        self.mcb.rd_data.connect();
        self.mcb.rd_empty.connect();
        self.dq.connect();
        self.a.connect();
        self.ba.connect();
        self.ras_n.connect();
        self.cas_n.connect();
        self.we_n.connect();
        self.odt.connect();
        self.cke.connect();
        self.dm.connect();
        self.udm.connect();
        self.dqs.connect();
        self.dqs_n.connect();
        self.udqs.connect();
        self.udqs_n.connect();
        self.ck.connect();
        self.ck_n.connect();
        self.rzq.connect();
        self.zio.connect();
    }
    fn hdl(&self) -> Verilog {
        Verilog::Wrapper(Wrapper {
            code: $code.into(),
            cores: $cores.into(),
        })
    }
}

    };
}

/// Instance of the MIG controller.
const MIG_INSTANCE: &str = r#"smartagg_mig mig(
    .mcb3_dram_dq(dq), .mcb3_dram_a(a), .mcb3_dram_ba(ba), .mcb3_dram_ras_n(ras_n),
    .mcb3_dram_cas_n(cas_n), .mcb3_dram_we_n(we_n), .mcb3_dram_odt(odt), .mcb3_dram_cke(cke),
    .mcb3_dram_dm(dm), .mcb3_dram_udqs(udqs), .mcb3_dram_udqs_n(udqs_n), .mcb3_rzq(rzq),
    .mcb3_zio(zio), .mcb3_dram_udm(udm), .mcb3_dram_dqs(dqs), .mcb3_dram_dqs_n(dqs_n),
    .mcb3_dram_ck(ck), .mcb3_dram_ck_n(ck_n),
    .c3_sys_clk_p(sys_clk_p), .c3_sys_clk_n(sys_clk_n), .c3_sys_rst_i(sys_rst),
    .c3_calib_done(mcb$calib_done), .c3_clk0(), .c3_rst0(),
    .c3_p0_cmd_clk(port_clk), .c3_p0_cmd_en(mcb$cmd_en), .c3_p0_cmd_instr(mcb$cmd_instr),
    .c3_p0_cmd_bl(mcb$cmd_bl), .c3_p0_cmd_byte_addr(mcb$cmd_addr), .c3_p0_cmd_empty(),
    .c3_p0_cmd_full(mcb$cmd_full), .c3_p0_wr_clk(port_clk), .c3_p0_wr_en(mcb$wr_en),
    .c3_p0_wr_mask(mcb$wr_mask), .c3_p0_wr_data(mcb$wr_data), .c3_p0_wr_full(mcb$wr_full),
    .c3_p0_wr_empty(), .c3_p0_wr_count(), .c3_p0_wr_underrun(), .c3_p0_wr_error(),
    .c3_p0_rd_clk(port_clk), .c3_p0_rd_en(mcb$rd_en), .c3_p0_rd_data(mcb$rd_data), .c3_p0_rd_full(),
    .c3_p0_rd_empty(mcb$rd_empty), .c3_p0_rd_count(), .c3_p0_rd_overflow(), .c3_p0_rd_error());"#;

ddr2_port!(
    /// The MIG DDR2 controller with one 32-bit user port (black box
    /// `smartagg_mig`); user side as [`crate::delay_line_ddr::DelayLineDdr`].
    MigDdr2,
    MIG_INSTANCE,
    MIG_DECLARATION
);

/// The DDR2 pins parked, for the designs whose delay line is on chip: the
/// memory is held in power-down (CKE low) with NOP commands (RAS#, CAS#,
/// WE# high), its clock stopped, ODT off, the data and strobe pins and the
/// MCB calibration pins left floating; the user port is never served
/// (calibration done, FIFOs empty, nothing full).
const PARKED_DDR2_MODULE: &str = r#"
module smartagg_ddr2_parked(
    inout wire [15:0] dq, output wire [12:0] a, output wire [2:0] ba,
    output wire ras_n, output wire cas_n, output wire we_n, output wire odt, output wire cke,
    output wire dm, output wire udm, inout wire dqs, inout wire dqs_n, inout wire udqs,
    inout wire udqs_n, output wire ck, output wire ck_n, inout wire rzq, inout wire zio,
    output wire calib_done, output wire cmd_full, output wire wr_full,
    output wire [31:0] rd_data, output wire rd_empty);
assign dq = 16'hzzzz;
assign {dqs, dqs_n, udqs, udqs_n, rzq, zio} = 6'bzzzzzz;
assign {a, ba} = 16'h0;
assign {ras_n, cas_n, we_n} = 3'b111;
assign {odt, cke, dm, udm, ck} = 5'b0;
assign ck_n = 1'b1;
assign {calib_done, cmd_full, wr_full, rd_data, rd_empty} = {1'b1, 1'b0, 1'b0, 32'h0, 1'b1};
endmodule
"#;

/// Instance of the parked DDR2 pins.
const PARKED_DDR2_INSTANCE: &str = r#"smartagg_ddr2_parked parked(
    .dq(dq), .a(a), .ba(ba), .ras_n(ras_n), .cas_n(cas_n), .we_n(we_n), .odt(odt), .cke(cke),
    .dm(dm), .udm(udm), .dqs(dqs), .dqs_n(dqs_n), .udqs(udqs), .udqs_n(udqs_n), .ck(ck),
    .ck_n(ck_n), .rzq(rzq), .zio(zio), .calib_done(mcb$calib_done), .cmd_full(mcb$cmd_full),
    .wr_full(mcb$wr_full), .rd_data(mcb$rd_data), .rd_empty(mcb$rd_empty));"#;

ddr2_port!(
    /// The XEM6310's DDR2 pins, parked ([`MigDdr2`]'s ports; no controller).
    ParkedDdr2,
    PARKED_DDR2_INSTANCE,
    PARKED_DDR2_MODULE
);
