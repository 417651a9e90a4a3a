//! Where the experiment studies differ from the paper, and why. Written
//! from earlier measured runs (the default runs under `study/results/`);
//! each summary prints its own numbers above these notes, and [`with_source`]
//! names the notes' figures as those earlier results, with their command.

/// Notes of the `nanoruler` study.
pub const NANORULER: &str = "\
1. **The marker spread claim (Fig. 7 left) does not hold, neither against the EMCCD nor against fixed frames.** \
The simulated EMCCD detects far more photons: 90 % QE against the SPCIMAGER's 35 % PDE × 26 % fill = 9.1 %, \
i.e. about 45,000 against 4,550 photo-electrons/s from a marker behind the splitter; even with its excess noise (F² = 2) \
and 30 ms of dead time per 64 ms frame the EMCCD's localisations carry about 5× the SPAD's information, and its marker \
spread is the smallest (≈ 9 nm against ≈ 13 nm for fixed frames and ≈ 16 nm for smart aggregation). The paper's \
experimental EMCCD evidently performed worse than this model of an iXon-class camera (unmodelled: its actual gain/noise, \
focus, drift, the intensity spread of ATTO 550 blinks); a simulation with the paper's own light levels cannot reproduce it.\n\
2. **Smart vs fixed depends on which blinks are counted.** Per marker, fixed 640-plane frames keep only the blinks bright \
enough for ThunderSTORM's wavelet threshold in a 64 ms frame (≈ 32 % of the blinks, the longest), while smart aggregation \
(the field design) localises ≈ 74 %, every blink that raises H to its open level, including many short, faint ones; its \
marker spread is therefore the larger. **On the same blinks** (table *Paired*), smart aggregation is more precise than \
fixed frames (fixed/smart RMS ≈ 1.2), which is the paper's point; the marker spread mixes precision with this selection.\n\
3. **Records per blink.** With the field design's association radius r_assoc = round(2σ) = 3 px, smart aggregation gives \
≈ 1.0 localisations per detected blink; with the paper's r_assoc = 1 on the same bit-planes ≈ 1.3, a slightly larger \
spread and, on the blinks shared with fixed frames, a ≈ 20 % larger error: the extra records are concurrent duplicate \
tracks (see `blink-durations`), opened later in the blink in ROIs shifted by about 2 px, and they inflate localisation \
counts and the density filter's neighbour counts.\n\
4. **False positives.** About 9–10 % of the smart localisations match no blink within 53.3 nm: background-only tracks (the \
field design bounds them at 1 per second over the field, at most 100 in this 100 s acquisition) and poor localisations of \
the short, faint blinks that the open level now admits; the density filter removes the isolated ones.\n\
5. **Neighbour distances** come out within ≈ 1–2 nm of 80 nm for every scheme with off-times of Exp(3 s) \
(`Scene::nanorulers`). With Exp(1 s) off-times (tried while building the study) neighbouring markers are often on \
together; the SPAD schemes, whose ROIs/frames then hold both markers, measured 75–77 nm and the EMCCD 78–80 nm.\n\
6. **Light.** Each camera gets the study's light (50,000 photons/s, 70,000 photons/s/µm²) behind the splitter. At half \
of it the derived window would be N = 326 planes (33 ms), longer than the mean blink of 30 ms.";

/// Notes of the `emccd-frames` study.
pub const EMCCD_FRAMES: &str = "\
1. **Dead time.** With 30 ms of every 64 ms lost, blinks shorter than the dead time can fall into it entirely: ≈ 58 % of \
10 ms and ≈ 72 % of 20 ms blinks are detected, and all blinks from ≈ 50 ms on. The paper notes this loss; its curve \
starts at the blinks the EMCCD still sees.\n\
2. **Merging** matters from ≈ 40 ms on, when blinks start to spread over two or more frames (1.2–2 localisations per \
blink unmerged); joining them within 40 nm lowers the error by 20–40 % at 70–100 ms. The paper's ≈ 20 % improvement \
from merging in its experimental data is at the low end of this range: without merging, the extra localisations from a \
blink spilling into the next frame are faint and poor; our ThunderSTORM-style detector misses many of the faintest \
(see `cameras`, mechanism 3), which makes the unmerged error here smaller than the paper's.\n\
3. **Level.** The simulated EMCCD error (≈ 16 nm at 10 ms down to ≈ 6 nm merged at 100 ms) is below the SPCIMAGER's at \
every duration (`smart-vs-fixed`), for the photon reason given in `nanoruler`.";

/// Notes of the `blink-durations` study.
pub const BLINK_DURATIONS: &str = "\
1. **The estimator's bias is small, not N − 1.** `t_e − t_s = t_drop − t_cross` (both shifted by ⌊N/2⌋). For the \
SPCIMAGER at 150× with the field design a track opens when the window holds about k_open ≈ 78 of N = 109 on-planes (the \
mean of H reaches T_open, 5.7 sd above background) and drops when it holds fewer than k_hold = N·√V_off/(√V_off + √V_on) \
≈ 41 (the paper's T), so the window adds N − k_open − k_hold ≈ −10 planes, plus one for the two-plane drop rule: \
≈ −1.0 ms, against a measured ≈ −0.3 ms on blinks with a single record (noise makes H reach T_open early). Subtracting \
the derived bias leaves ≈ +0.7 ms, well inside the per-blink scatter (≈ 3 ms). A window that crossed its threshold on its \
first on-plane (a much brighter molecule) would add N − 1 planes; both thresholds sit at large fractions of the on-signal, \
so it does not.\n\
2. **Missing short blinks.** A blink is detected when it raises H to the open level, which keeps background within 1 false \
blink/s over the field: smart aggregation detects ≈ 80 % of these blinks (predicted ≥ 90 % from ≈ 11 ms on; 77 % of 10 ms \
blinks in `smart-vs-fixed`), and ≈ 3 % of its records match no blink. The paper's one threshold would show shorter blinks but \
also ≈ 500 false blinks/s over a 32×32 field. So the smart histogram is thinned below ≈ 10 ms, while the true exponential is \
largest there. The EMCCD histogram is coarse (64 ms bins) and loses ≈ 30 % of blinks to the dead time; a 100 ms blink spans \
two or three frames.\n\
3. **Why one blink gives several records with r_assoc = 1, and one with the field design.** Almost every split is a \
*concurrent* track: while the first track is on, the local maximum of H wanders and a candidate at the open level appears \
2 px (Chebyshev) from the first anchor — beyond r_assoc = 1 — and opens a second track; both then stay on until the blink \
ends, because each tests the 3×3 around its own anchor, which still sees the molecule. Drops and restarts within a blink \
(two planes below T_hold) are rare. The second track opens some ms after the first; its record sums the remaining planes \
into an ROI shifted by 2 px, so it duplicates most of the first record's photons rather than sharing them. With the \
paper's r_assoc = 1 the same bit-planes give 1.1 (blinks under 20 ms) to 2.1 (over 100 ms) records per blink; the field \
design's r_assoc = round(2σ) = 3 gives 1.0 at every duration with the same detection. This is why the field design (and \
`smartagg aggregate`) associates within 2σ.";

/// Notes of the `detection` study.
pub const DETECTION: &str = "\
1. **Eq. 5's ≈ 99 % holds** for a molecule centred on a pixel and on for the whole window, and the model's exact \
lattice statistics predict the measured detection probability to within its interval at every (N, T). The Gaussian \
approximation is good for detection (the on-signal sums many photons) but **misses the background tail**: the exact \
false-alarm probability per pixel-plane at Eq. 7's threshold is about 2× the Gaussian 1.35e-3, and 3–13× at z = 3.5–4 or \
small N, because H of the background is a sum of few Bernoulli counts and is right-skewed. In the default run the \
measured false-alarm rate matches the exact value (2.79e-3 against 2.77e-3 at the derived N and T). The intervals treat \
neighbouring pixels, which share bits through the kernel, as independent, so they are somewhat too narrow; all (N, z) \
share one background recording, so a fluctuation of its mean count moves every tail the same way (the `--quick` run's \
came out ≈ 15 % above exact).\n\
2. **The per-window promise is not the per-blink detection rate.** Eq. 5 promises detection at the paper's threshold \
for a molecule on for a whole window; the field design opens a track only at T_open, which keeps background within 1 false \
blink/s over the field (5.7 sd of background H at the derived N, where Eq. 7's T is 3 sd). In part B, blinks of \
Exp(30 ms) durations are detected 69–80 %, limited by the open level and by blinks shorter than the window.\n\
3. **Time resolution against precision.** A quarter of the derived N (2.7 ms window) detects fewer blinks (69 % against \
79 %), its noisy H splits tracks (≈ 2.3 records per blink, which inflates the localisations per second) and each \
localisation is poorer (RMS ≈ 30 nm against 21 nm); half N detects the most (80 %) with 1.4 records per blink and 23 nm; \
twice N gives the same error as N but detects 74 %, missing blinks shorter than its window. The paper's N sits at the \
best detection with one record per blink.";

/// `notes` of the study `study`, preceded by the sentence that names their
/// figures as earlier results of the default run, with its command.
pub fn with_source(study: &str, notes: &str) -> String {
    format!(
        "*The figures quoted below are earlier results, not this run's: they come from the default run \
         `smartagg study {study} --out DIR` (its defaults, seed 1), committed in \
         `study/results/{study}/summary.md`. This run's own figures are the tables above.*\n\n{notes}"
    )
}
