//! Where the experiment studies differ from the paper, and why. Written
//! from earlier measured runs (the default runs under `study/results/`);
//! each summary prints its own numbers above these notes, and [`with_source`]
//! names the notes' figures as those earlier results, with their command.

/// Notes of the `nanoruler` study.
pub const NANORULER: &str = "\
1. **The marker spread claim (Fig. 7 left) does not hold against the EMCCD, and barely against fixed frames.** \
The simulated EMCCD detects far more photons: 90 % QE against the SPCIMAGER's 35 % PDE × 26 % fill = 9.1 %, \
i.e. about 45,000 against 4,550 photo-electrons/s from a marker behind the splitter; even with its excess noise (F² = 2) \
and 30 ms of dead time per 64 ms frame the EMCCD's localisations carry about 5× the SPAD's information, and its marker \
spread is the smallest (≈ 8 nm against ≈ 12–13 nm). The paper's experimental EMCCD evidently performed worse than this \
model of an iXon-class camera (unmodelled: its actual gain/noise, focus, drift, the intensity spread of ATTO 550 blinks); \
a simulation with the paper's own light levels cannot reproduce it.\n\
2. **Smart vs fixed depends on which blinks are counted.** Per marker, fixed 640-plane frames keep only the blinks bright \
enough for ThunderSTORM's wavelet threshold in a 64 ms frame (≈ 30 % of the blinks, the longest), while smart aggregation \
localises ≈ 55 % (everything longer than L_min ≈ 22 ms), including many short, faint blinks; the two spreads therefore \
come out about equal. **On the same blinks** (table *Paired*), smart aggregation is more precise than fixed frames \
(fixed/smart RMS ≈ 1.15), which is the paper's point; the marker spread mixes precision with this selection.\n\
3. **Records per blink.** With the model's default r_assoc = 1, smart aggregation gives ≈ 1.7 localisations per detected \
blink; with r_assoc = 3 ≈ 1.05 at the same error and spread. The extra records are concurrent duplicate tracks (see \
`blink-durations`): they sum nearly the same photons, so they neither help nor hurt the spread much, but they inflate \
localisation counts and the density filter's neighbour counts.\n\
4. **Neighbour distances** come out within ≈ 1–2 nm of 80 nm for every scheme with off-times of Exp(3 s) \
(`Scene::nanorulers`). With Exp(1 s) off-times (tried while building the study) neighbouring markers are often on \
together; the SPAD schemes, whose ROIs/frames then hold both markers, measured 75–77 nm and the EMCCD 78–80 nm.\n\
5. **Light.** Each camera gets the study's light (50,000 photons/s, 70,000 photons/s/µm²) behind the splitter. At half \
of it the derived window would be N = 326 with L_min = 613 planes, and smart aggregation would find 16 % of 30 ms blinks.";

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
SPCIMAGER at 150× the crossing on-count k* = N·√V_off/(√V_off + √V_on) ≈ 42 of N = 109 planes, so the rolling window \
adds N − 2k* ≈ 25 planes, plus one for the two-plane drop rule: ≈ 2.7 ms, against a measured ≈ 3 ms on blinks with a single \
record. Subtracting the derived bias leaves a few tenths of a ms, well inside the per-blink scatter (≈ 3 ms). A window \
that crossed T on its first on-plane (a much brighter molecule) would add N − 1 planes; the paper's threshold sits at a \
large fraction of the on-signal, so it does not.\n\
2. **Missing short blinks.** Smart aggregation confirms only tracks longer than L_min ≈ 21 ms (from the false-alarm \
statistics); the paper's L_min = 1 would show shorter blinks but also ≈ 500 false blinks/s over a 32×32 field. So the \
smart histogram is cut below ≈ 20 ms, while the true exponential is largest there. The EMCCD histogram is coarse (64 ms \
bins) and loses ≈ 30 % of blinks to the dead time; a 100 ms blink spans two or three frames.\n\
3. **Why one blink gives about two records (r_assoc = 1).** Almost every split is a *concurrent* track: while the first \
track is on, the local maximum of H wanders and a candidate appears 2 px (Chebyshev) from the first anchor — beyond \
r_assoc = 1 — and opens a second track; both then stay on until the blink ends, because each tests the 3×3 around its own \
anchor, which still sees the molecule. Drops and restarts within a blink (two planes below T) are rare. The second \
track opens some ms after the first; its record sums the remaining planes into an ROI shifted by 2 px, so it duplicates \
most of the first record's photons rather than sharing them. With r_assoc = 3 the same bit-planes give ≈ 1.0 records per \
blink with the same detection. The `smart-vs-fixed` study's 1.9 localisations per blink at 50 ms are these duplicates: \
they count twice in its RMS error (correlated, so the error per localisation is about unchanged) and double its \
localisation counts. A fix belongs in the model (a larger default r_assoc ≈ 2σ, as the demo uses, or suppressing \
candidates whose 3×3 overlaps a live anchor's), not in the study.";

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
2. **The per-window promise is not the per-blink detection rate.** A real blink is detected only if the track lasts \
L_min planes: in part B, blinks of Exp(30 ms) durations are detected 42–71 %, limited by L_min (which must grow with \
the false-alarm rate of a shorter window) and by blinks shorter than the window.\n\
3. **Time resolution against precision.** A quarter of the derived N (2.7 ms window) localises more of the short blinks \
(70 % against 60 % of the blinks) but with a noisier H, so tracks split (≈ 3.3 records per blink, which inflates the \
localisations per second) and each localisation is poorer (RMS ≈ 27 nm against 19 nm); twice N gives the best error per localisation but detects under half of the \
blinks. The paper's N sits where the detection per window reaches 99 %.";

/// `notes` of the study `study`, preceded by the sentence that names their
/// figures as earlier results of the default run, with its command.
pub fn with_source(study: &str, notes: &str) -> String {
    format!(
        "*The figures quoted below are earlier results, not this run's: they come from the default run \
         `smartagg study {study} --out DIR` (its defaults, seed 1), committed in \
         `study/results/{study}/summary.md`. This run's own figures are the tables above.*\n\n{notes}"
    )
}
