//! Opal Kelly FrontPanel endpoints as black boxes: `okHost`, `okWireOR`
//! and the endpoints `okWireIn`, `okWireOut`, `okTriggerIn`, `okBTPipeIn`
//! and `okBTPipeOut`, instantiated by name, with `(* blackbox *)` port
//! declarations written from Opal Kelly's public FrontPanel user's manual
//! (stub bodies only drive outputs to 0, so that Verilator can lint the
//! design). A part of the XEM6310 top ([`crate::xem6310`]): the host
//! interface, which has no model twin (FrontPanel's host protocol is Opal
//! Kelly's and is not modelled).

use rust_hdl::prelude::*;

/// Port declarations of the FrontPanel endpoints used here (black boxes).
const FRONTPANEL_DECLARATIONS: &str = r#"
(* blackbox *)
module okHost(input wire [4:0] okUH, output wire [2:0] okHU, inout wire [31:0] okUHU,
    inout wire okAA, output wire okClk, output wire [112:0] okHE, input wire [64:0] okEH);
assign okHU = 3'h0;
assign okClk = 1'b0;
assign okHE = 113'h0;
endmodule
(* blackbox *)
module okWireOR #(parameter N = 1) (output wire [64:0] okEH, input wire [N*65-1:0] okEHx);
assign okEH = 65'h0;
endmodule
(* blackbox *)
module okWireIn(input wire [112:0] okHE, input wire [7:0] ep_addr, output wire [31:0] ep_dataout);
assign ep_dataout = 32'h0;
endmodule
(* blackbox *)
module okWireOut(input wire [112:0] okHE, output wire [64:0] okEH, input wire [7:0] ep_addr,
    input wire [31:0] ep_datain);
assign okEH = 65'h0;
endmodule
(* blackbox *)
module okTriggerIn(input wire [112:0] okHE, input wire [7:0] ep_addr, input wire ep_clk,
    output wire [31:0] ep_trigger);
assign ep_trigger = 32'h0;
endmodule
(* blackbox *)
module okBTPipeIn(input wire [112:0] okHE, output wire [64:0] okEH, input wire [7:0] ep_addr,
    output wire ep_write, output wire ep_blockstrobe, output wire [31:0] ep_dataout,
    input wire ep_ready);
assign okEH = 65'h0;
assign ep_write = 1'b0;
assign ep_blockstrobe = 1'b0;
assign ep_dataout = 32'h0;
endmodule
(* blackbox *)
module okBTPipeOut(input wire [112:0] okHE, output wire [64:0] okEH, input wire [7:0] ep_addr,
    output wire ep_read, output wire ep_blockstrobe, input wire [31:0] ep_datain,
    input wire ep_ready);
assign okEH = 65'h0;
assign ep_read = 1'b0;
assign ep_blockstrobe = 1'b0;
endmodule
"#;

/// FrontPanel `okHost` (black box); carries the declarations of every
/// FrontPanel module used.
#[derive(LogicBlock, Default)]
pub struct OkHost {
    /// Host-interface inputs (pins).
    pub ok_uh: Signal<In, Bits<5>>,
    /// Host-interface outputs (pins).
    pub ok_hu: Signal<Out, Bits<3>>,
    /// Host-interface data (pins).
    pub ok_uhu: Signal<InOut, Bits<32>>,
    /// Host-interface strobe (pin).
    pub ok_aa: Signal<InOut, Bit>,
    /// The host-interface clock, 100.8 MHz.
    pub ok_clk: Signal<Out, Clock>,
    /// Host to endpoints bus.
    pub ok_he: Signal<Out, Bits<113>>,
    /// Endpoints to host bus (through okWireOR).
    pub ok_eh: Signal<In, Bits<65>>,
}

impl Logic for OkHost {
    fn update(&mut self) {}
    fn connect(&mut self) {
        self.ok_hu.connect();
        self.ok_clk.connect();
        self.ok_he.connect();
        self.ok_uhu.connect();
        self.ok_aa.connect();
    }
    fn hdl(&self) -> Verilog {
        Verilog::Wrapper(Wrapper {
            code: "okHost host(.okUH(ok_uh), .okHU(ok_hu), .okUHU(ok_uhu), .okAA(ok_aa), \
                   .okClk(ok_clk), .okHE(ok_he), .okEH(ok_eh));"
                .into(),
            cores: FRONTPANEL_DECLARATIONS.into(),
        })
    }
}

/// FrontPanel `okWireOR` of `N` endpoint buses (`NB = 65·N` bits).
#[derive(LogicBlock)]
pub struct OkWireOr<const NB: usize> {
    /// To okHost.
    pub ok_eh: Signal<Out, Bits<65>>,
    /// The endpoints' buses, 65 bits each.
    pub ok_ehx: Signal<In, Bits<NB>>,
}

impl<const NB: usize> Default for OkWireOr<NB> {
    fn default() -> Self {
        assert_eq!(NB % 65, 0, "65 bits per endpoint");
        OkWireOr {
            ok_eh: Default::default(),
            ok_ehx: Default::default(),
        }
    }
}

impl<const NB: usize> Logic for OkWireOr<NB> {
    fn update(&mut self) {}
    fn connect(&mut self) {
        self.ok_eh.connect();
    }
    fn hdl(&self) -> Verilog {
        Verilog::Wrapper(Wrapper {
            code: format!(
                "okWireOR #(.N({})) wire_or(.okEH(ok_eh), .okEHx(ok_ehx));",
                NB / 65
            ),
            cores: String::new(),
        })
    }
}

/// One FrontPanel endpoint (black box): `okWireIn`, `okWireOut`,
/// `okTriggerIn`, `okBTPipeIn` or `okBTPipeOut` at address `addr`.
#[derive(LogicBlock)]
pub struct OkEndpoint {
    /// Host to endpoints bus.
    pub ok_he: Signal<In, Bits<113>>,
    /// This endpoint's bus to okWireOR (unused by wire-ins and triggers).
    pub ok_eh: Signal<Out, Bits<65>>,
    /// Clock (trigger-ins).
    pub ep_clk: Signal<In, Clock>,
    /// Wire-in value, trigger pulses, pipe-in data.
    pub ep_dataout: Signal<Out, Bits<32>>,
    /// Wire-out value, pipe-out data.
    pub ep_datain: Signal<In, Bits<32>>,
    /// Pipe-in write / pipe-out read strobe.
    pub ep_strobe: Signal<Out, Bit>,
    /// Pipes: a block can be transferred.
    pub ep_ready: Signal<In, Bit>,
    _kind: EndpointKind,
    _addr: u8,
}

/// Which FrontPanel endpoint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EndpointKind {
    /// `okWireIn`.
    WireIn,
    /// `okWireOut`.
    WireOut,
    /// `okTriggerIn`.
    TriggerIn,
    /// `okBTPipeIn`.
    BtPipeIn,
    /// `okBTPipeOut`.
    BtPipeOut,
}

impl OkEndpoint {
    /// An endpoint of `kind` at `addr`.
    pub fn new(kind: EndpointKind, addr: u8) -> Self {
        OkEndpoint {
            ok_he: Default::default(),
            ok_eh: Default::default(),
            ep_clk: Default::default(),
            ep_dataout: Default::default(),
            ep_datain: Default::default(),
            ep_strobe: Default::default(),
            ep_ready: Default::default(),
            _kind: kind,
            _addr: addr,
        }
    }

    /// Whether the endpoint drives a bus into okWireOR.
    pub fn has_bus(&self) -> bool {
        !matches!(self._kind, EndpointKind::WireIn | EndpointKind::TriggerIn)
    }
}

impl Logic for OkEndpoint {
    fn update(&mut self) {}
    fn connect(&mut self) {
        self.ok_eh.connect();
        self.ep_dataout.connect();
        self.ep_strobe.connect();
    }
    fn hdl(&self) -> Verilog {
        let a = self._addr;
        let code = match self._kind {
            EndpointKind::WireIn => format!(
                "okWireIn ep(.okHE(ok_he), .ep_addr(8'h{a:02x}), .ep_dataout(ep_dataout));\n\
                 assign ok_eh = 65'h0;\nassign ep_strobe = 1'b0;"
            ),
            EndpointKind::WireOut => format!(
                "okWireOut ep(.okHE(ok_he), .okEH(ok_eh), .ep_addr(8'h{a:02x}), .ep_datain(ep_datain));\n\
                 assign ep_dataout = 32'h0;\nassign ep_strobe = 1'b0;"
            ),
            EndpointKind::TriggerIn => format!(
                "okTriggerIn ep(.okHE(ok_he), .ep_addr(8'h{a:02x}), .ep_clk(ep_clk), .ep_trigger(ep_dataout));\n\
                 assign ok_eh = 65'h0;\nassign ep_strobe = 1'b0;"
            ),
            EndpointKind::BtPipeIn => format!(
                "okBTPipeIn ep(.okHE(ok_he), .okEH(ok_eh), .ep_addr(8'h{a:02x}), .ep_write(ep_strobe), \
                 .ep_blockstrobe(), .ep_dataout(ep_dataout), .ep_ready(ep_ready));"
            ),
            EndpointKind::BtPipeOut => format!(
                "okBTPipeOut ep(.okHE(ok_he), .okEH(ok_eh), .ep_addr(8'h{a:02x}), .ep_read(ep_strobe), \
                 .ep_blockstrobe(), .ep_datain(ep_datain), .ep_ready(ep_ready));\n\
                 assign ep_dataout = 32'h0;"
            ),
        };
        Verilog::Wrapper(Wrapper {
            code,
            cores: String::new(),
        })
    }
}
