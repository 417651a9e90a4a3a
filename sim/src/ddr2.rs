//! A behavioural Verilog model of one 32-bit Spartan-6 MCB user port (the
//! MIG DDR2 controller's black box), verilated with the design so that the
//! DDR2 delay line runs at Verilator speed.
//!
//! Behaviour (the protocol of Xilinx UG388 as the gateware uses it, and the
//! same rules as `smartagg_hdl::testbench::mcb_model::McbModel`): a 4-entry command
//! FIFO executed in order, 64-word write and read data FIFOs, a command's
//! first word no sooner than `LATENCY` clocks after it was issued, one word
//! per clock, a refresh gap of `REFRESH_GAP` clocks every `REFRESH_EVERY`
//! clocks (a refresh that starts while commands wait is counted as a
//! *refresh collision*), calibration after `CALIB` clocks, and a
//! pseudo-random word at every address never written (DDR2 after power-up).
//! Protocol errors (a full FIFO written, a read of an empty FIFO, a write
//! command without its data, an address beyond the modelled memory) raise
//! the sticky `error`.

/// Timing of the DDR2 model (clocks of the pipeline clock).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Ddr2Timing {
    /// Clocks from a command to its first word.
    pub latency: u32,
    /// Clocks between refreshes (tREFI: 7.8 µs = 786 clocks at 100.8 MHz).
    pub refresh_every: u32,
    /// Clocks a refresh takes (tRFC and the controller's overhead).
    pub refresh_gap: u32,
    /// Clocks to calibration done.
    pub calib: u32,
    /// Seed of the power-up garbage.
    pub seed: u32,
}

impl Default for Ddr2Timing {
    /// DDR2-800 behind the MCB at 100.8 MHz: ≈ 20 clocks of command
    /// latency, a refresh every 7.8 µs taking ≈ 0.3 µs.
    fn default() -> Self {
        Ddr2Timing {
            latency: 20,
            refresh_every: 786,
            refresh_gap: 30,
            calib: 400,
            seed: 0x5eed_d0d0,
        }
    }
}

/// The Verilog of module `cosim_ddr2` with `aw` word-address bits of memory.
pub fn verilog(aw: usize, t: &Ddr2Timing) -> String {
    format!(
        r#"
// Behavioural MCB user port (simulation only), written for smartagg-sim.
module cosim_ddr2(clock, calib_done, cmd_en, cmd_instr, cmd_bl, cmd_addr, cmd_full,
    wr_en, wr_mask, wr_data, wr_full, rd_en, rd_data, rd_empty, error, refresh_collisions,
    refreshes);
    input wire clock;
    output reg calib_done;
    input wire cmd_en;
    input wire [2:0] cmd_instr;
    input wire [5:0] cmd_bl;
    input wire [29:0] cmd_addr;
    output reg cmd_full;
    input wire wr_en;
    input wire [3:0] wr_mask;
    input wire [31:0] wr_data;
    output reg wr_full;
    input wire rd_en;
    output reg [31:0] rd_data;
    output reg rd_empty;
    output reg error;
    output reg [31:0] refresh_collisions;
    output reg [31:0] refreshes;
    localparam AW = {aw};
    localparam LATENCY = 64'd{lat};
    localparam REFRESH_EVERY = 64'd{every};
    localparam REFRESH_GAP = 32'd{gap};
    localparam CALIB = 64'd{calib};
    localparam SEED = 32'h{seed:08x};
    reg [31:0] mem [0:(1<<AW)-1];
    reg written [0:(1<<AW)-1];
    reg cw [0:3];
    reg [27:0] ca [0:3];
    reg [6:0] cn [0:3];
    reg [63:0] cat [0:3];
    reg [1:0] ch, ct;
    reg [2:0] cc;
    reg [31:0] wq [0:63];
    reg [5:0] wh, wt;
    reg [6:0] wc;
    reg [31:0] rq [0:63];
    reg [5:0] rh, rt;
    reg [6:0] rc;
    reg [63:0] cycle, next_refresh;
    reg [31:0] refresh_left, coll, nref;
    reg op, op_w, err;
    reg [27:0] op_a;
    reg [6:0] op_n;
    reg [31:0] g;
    integer i;
    initial begin
        for (i = 0; i < (1<<AW); i = i + 1) written[i] = 1'b0;
        ch = 0; ct = 0; cc = 0; wh = 0; wt = 0; wc = 0; rh = 0; rt = 0; rc = 0;
        cycle = 0; next_refresh = REFRESH_EVERY; refresh_left = 0; coll = 0; nref = 0;
        op = 0; op_w = 0; err = 0; op_a = 0; op_n = 0;
        calib_done = 0; cmd_full = 0; wr_full = 0; rd_data = 0; rd_empty = 1; error = 0;
        refresh_collisions = 0; refreshes = 0;
    end
    always @(posedge clock) begin
        cycle = cycle + 1;
        if (cmd_en) begin
            if (cc < 4 && cmd_instr <= 3'd1 && cmd_addr[29:AW+2] == 0) begin
                cw[ct] = (cmd_instr == 3'd0);
                ca[ct] = cmd_addr[29:2];
                cn[ct] = {{1'b0, cmd_bl}} + 7'd1;
                cat[ct] = cycle;
                ct = ct + 1;
                cc = cc + 1;
            end else err = 1;
        end
        if (wr_en) begin
            if (wc < 64 && wr_mask == 0) begin
                wq[wt] = wr_data; wt = wt + 1; wc = wc + 1;
            end else err = 1;
        end
        if (rd_en) begin
            if (rc == 0) err = 1;
            else begin rh = rh + 1; rc = rc - 1; end
        end
        if (refresh_left != 0) refresh_left = refresh_left - 1;
        else if (op) begin
            if (op_w) begin
                if (wc == 0) err = 1;
                else begin
                    mem[op_a[AW-1:0]] = wq[wh]; written[op_a[AW-1:0]] = 1'b1;
                    wh = wh + 1; wc = wc - 1;
                    op_a = op_a + 1; op_n = op_n - 1; if (op_n == 0) op = 0;
                end
            end else if (rc < 64) begin
                g = SEED ^ ({{4'b0, op_a}} * 32'h9E3779B9);
                g = g ^ (g >> 15); g = g * 32'h85EBCA6B; g = g ^ (g >> 13);
                rq[rt] = written[op_a[AW-1:0]] ? mem[op_a[AW-1:0]] : g;
                rt = rt + 1; rc = rc + 1;
                op_a = op_a + 1; op_n = op_n - 1; if (op_n == 0) op = 0;
            end else err = 1;
        end else if (cycle >= next_refresh) begin
            refresh_left = REFRESH_GAP;
            next_refresh = cycle + REFRESH_EVERY;
            nref = nref + 1;
            if (cc != 0) coll = coll + 1;
        end else if (cycle >= CALIB && cc != 0 && cycle >= cat[ch] + LATENCY) begin
            op = 1; op_w = cw[ch]; op_a = ca[ch]; op_n = cn[ch];
            ch = ch + 1; cc = cc - 1;
        end
        calib_done <= cycle >= CALIB;
        cmd_full <= cc >= 4;
        wr_full <= wc >= 64;
        rd_empty <= rc == 0;
        rd_data <= rq[rh];
        error <= err;
        refresh_collisions <= coll;
        refreshes <= nref;
    end
endmodule
"#,
        lat = t.latency,
        every = t.refresh_every,
        gap = t.refresh_gap,
        calib = t.calib,
        seed = t.seed,
    )
}
