//! A multiply by a constant weight, `y = w · x mod 2^W`: shift-and-add in
//! LUTs (one adder or subtractor per non-zero canonical signed digit after
//! the first, [`csd_digits`]), or a DSP48A1 slice. The spatial filter's
//! kernel multiplies ([`crate::spatial_filter`]) and the bank base address
//! `slot · R` of the ROI aggregator and the packetiser use it.

use rust_hdl::prelude::*;

/// The signed binary digits of `weight` with no two adjacent non-zero
/// (canonical signed digit form), as `(shift, negative)`, most significant
/// first: the fewest shifted adds and subtracts that make `weight · x`
/// (29 = 32 − 4 + 1: three terms where its binary form has four).
pub fn csd_digits(weight: u32) -> Vec<(u32, bool)> {
    let mut digits = Vec::new();
    let mut w = weight as i64;
    let mut shift = 0;
    while w != 0 {
        if w & 1 == 1 {
            // w ≡ 1 (mod 4): +1, w ≡ 3 (mod 4): −1, so that w − d ≡ 0 (mod 4).
            let d = 2 - (w & 3);
            digits.push((shift, d < 0));
            w -= d;
        }
        w >>= 1;
        shift += 1;
    }
    digits.reverse();
    digits
}

/// Adders or subtractors the shift-and-add form of a multiply by `weight`
/// takes (what a DSP slice saves): one fewer than its signed digits.
pub fn csd_adders(weight: u32) -> usize {
    csd_digits(weight).len().saturating_sub(1)
}

/// `y = w · x mod 2^W` for a constant weight w: in LUTs, a chain of
/// shifted adds and subtracts ([`csd_digits`], the leading digit positive;
/// a partial sum may wrap, the product, which the caller guarantees to fit
/// W bits, does not); or, [`ConstMul::dsp`], a multiply that synthesis puts
/// in a DSP48A1 slice (its operand narrowed to the bits the caller says it
/// holds, at most 17: one slice's unsigned operand).
#[derive(LogicBlock)]
pub struct ConstMul<const W: usize> {
    /// Operand.
    pub x: Signal<In, Bits<W>>,
    /// Product (the caller guarantees it fits W bits).
    pub y: Signal<Out, Bits<W>>,
    _weight: u32,
    _dsp_operand_bits: Option<usize>,
}

/// The widest unsigned operand of one DSP48A1 multiplier (18-bit signed).
pub const DSP_OPERAND_BITS: usize = 17;

impl<const W: usize> ConstMul<W> {
    /// Multiplier by `weight`, shift-and-add.
    pub fn new(weight: u32) -> Self {
        ConstMul {
            x: Default::default(),
            y: Default::default(),
            _weight: weight,
            _dsp_operand_bits: None,
        }
    }

    /// Multiplier by `weight` in a DSP slice, for operands below
    /// `2^operand_bits` (`operand_bits ≤` [`DSP_OPERAND_BITS`]).
    pub fn dsp(weight: u32, operand_bits: usize) -> Self {
        assert!(
            (1..=DSP_OPERAND_BITS.min(W)).contains(&operand_bits),
            "a DSP48A1 operand of {operand_bits} bits"
        );
        ConstMul {
            _dsp_operand_bits: Some(operand_bits),
            ..ConstMul::new(weight)
        }
    }

    /// [`ConstMul::dsp`] with the operand bits given, else [`ConstMul::new`].
    pub fn of((weight, dsp_operand_bits): (u32, Option<usize>)) -> Self {
        match dsp_operand_bits {
            Some(bits) => ConstMul::dsp(weight, bits),
            None => ConstMul::new(weight),
        }
    }
}

impl<const W: usize> Logic for ConstMul<W> {
    fn update(&mut self) {
        // (`to_u64`: `index` refuses vectors wider than 32 bits.)
        let mut x = self.x.val().to_u64() as u128;
        if let Some(b) = self._dsp_operand_bits {
            x &= (1u128 << b) - 1;
        }
        // x < 2^64 and w < 2^32: the product fits 128 bits.
        let y = (x * self._weight as u128) & ((1u128 << W) - 1);
        self.y.next = (y as u64).to_bits();
    }

    fn connect(&mut self) {
        self.y.connect();
    }

    fn hdl(&self) -> Verilog {
        let w = self._weight;
        let expr = match self._dsp_operand_bits {
            Some(b) => format!("x[{}:0] * {W}'d{w}", b - 1),
            None if w == 0 => format!("{W}'d0"),
            None => {
                let mut e = String::new();
                for (i, &(shift, negative)) in csd_digits(w).iter().enumerate() {
                    let op = match (i, negative) {
                        (0, _) => "",
                        (_, true) => " - ",
                        (_, false) => " + ",
                    };
                    e.push_str(&format!("{op}(x << {shift})"));
                }
                e
            }
        };
        // rust-hdl declares the output a reg.
        Verilog::Custom(format!("always @(*) y = {expr};"))
    }
}
