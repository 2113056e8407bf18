#!/usr/bin/env python3
"""Recompute the tables of a hard-disk report of `clv analyze` from its frames.

    python3 scripts/verify_report.py REPORT_DIR FRAMES.mcap   # exit 1 on a disagreement
    python3 scripts/verify_report.py REPORT_DIR FRAMES.mcap --run RUN_DIR   # lambda_gs from R_n too

REPORT_DIR is the --out of `clv analyze FRAMES.mcap`, FRAMES.mcap a frame file of
`clv backward --with-gs --out FRAMES.mcap` (without GS vectors the GS columns of localization.csv and projections.csv must be NaN, and the other GS tables are skipped).
Each quantity is recomputed here with numpy from the frames alone (read by read_frames.py)
and compared with the report's CSV files. The tables compared column by column must hold
exactly the expected rows (i = 1..k; one per frame; each chosen i with each Delta), none
deleted, repeated or renumbered, and no column that nothing here recomputes:

  spectrum.csv         lambda_clv = mean over all frames of the local CLV exponents,
                       lambda_gs_window = mean over all frames of the local GS exponents, and
                       their errors stderr_clv, stderr_gs_window (batch means, below);
  local_exponents.csv  time and lambda_i of each row's frame (matched by step): the frame's time
                       and its local CLV exponent i, ln |D phi^tau v^i| / tau, as the frame holds it;
  finite_time_exponents.csv   for each (i, delta): the local exponents averaged over consecutive
                       windows of delta frames counted from the NEWEST frame (the oldest T mod
                       delta frames fill no window), and windows = their number, mean, std (n - 1;
                       NaN from one window), min and max of exponent i over them;
  domination.csv       for each delta, over the same windows: a pair (i, i + 1) swaps in a window
                       where exponent i + 1 exceeds exponent i; overall = the swap fraction over
                       all windows and all D - 1 pairs, outside_null = the same over the pairs not
                       both inside the null space 2N-2..2N+3 (the two pairs that straddle its
                       borders count), pair_i_j = one pair's, border_unstable_null and
                       border_null_stable = the pairs (2N-3, 2N-2) and (2N+3, 2N+4),
                       split_unstable_null (split_null_stable) = the fraction of windows where some
                       exponent of 1..2N-3 lies below some of 2N-2..2N+3 (some of 2N-2..2N+3 below
                       some of 2N+4..D); a column not recomputed here is a disagreement;
  domination_pairs.csv for every pair i = 1..k-1 (the rows) and delta (delta_<delta>): the
                       share of the same windows where exponent i + 1 exceeds exponent i (NaN
                       where none fits);
  localization.csv     W_gs, W_clv: W_i = exp(<S_i>) / N with S = -sum_n mu_n ln mu_n, mu_n the
                       share of |v|^2 on disk n (its dq_x, dq_y, dp_x, dp_y); stderr_gs,
                       stderr_clv = W times the batch-means error of <S> over the sampled frames;
  projections.csv      eta_q = <|dq|^2>, eta_p = <|dp|^2> and <cos Theta> = <dq.dp / |dq||dp|>
                       for GS and CLV; a frame whose |dq|^2 or |dp|^2 is below 1e-24 (round-off:
                       a pure position or momentum vector, as the null-space GS vectors) has no
                       Theta and is left out of the mean, which is NaN where no frame has one;
                       eta_q_gs_std, eta_q_clv_std = sample std (n - 1) of |dq|^2 over the frames;
  overlap_gs_clv.csv   abs_g_dot_v_mean = <|g^i . v^i|>, abs_g_dot_v_std its sample std (n - 1);
  overlap_clv_gs.csv   abs_vJ_mean = <|v^J . g^i|>, overlap_clv_clv.csv abs_vJ_mean = <|v^J . v^i|>,
                       and abs_vJ_std the sample std (n - 1) of each over the sampled frames;
  nullspace_alpha.csv, nullspace_beta.csv   g^i . e_k and v^i . e_k (and the row norms) of the six
                       null-space vectors at the earliest sampled frame, with the natural basis
                       e_1 = (p, 0)/|p|, e_2, e_3 = x, y translations of the positions,
                       e_4 = (0, p)/|p|, e_5, e_6 = x, y translations of the momenta;
  nullspace_tables.json  the same two matrices (beta, and alpha with GS vectors), n, the
                       indices 2N-2..2N+3, and the step and time of that frame (its note, a
                       fixed text, is not compared);
  nullspace_series.csv for each sampled frame (by step): time; angle_clv (angle_gs) = the largest
                       principal angle between the span of the six null-space CLVs (GS vectors)
                       and span{e_1..e_6}, angle_gs_clv = that between the two six-vector spans
                       (NaN without GS vectors); norm_beta_i, norm_alpha_i = the row norms of
                       beta and alpha (sqrt(sum_k (v^i . e_k)^2)). Principal angles: here
                       atan2 of the singular values of Q_b - Q_a Q_a^T Q_b and Q_a^T Q_b
                       (sines and cosines), Q from an SVD (clv: QR, asin below pi/4). The three
                       angles are round-off (clv ~1e-13, here the same size but other digits: a
                       factor 3 apart seen), so within 1e-10 they say only that both sides find
                       the spans to coincide; the six null CLVs are nearly dependent (the last
                       three turn onto the first three like 1/s), which amplifies round-off by
                       about the window's length in time, and a far longer window than the
                       test's could bring angle_clv near 1e-10, where two round-offs may differ
                       by more than the tolerance;
  transversality.csv   for each sampled frame (by step): psi_unstable_stable = the smallest
                       principal angle between E^u = v^1..v^(2N-3) and E^s = v^(2N+4)..v^D, and
                       phi_a_b = that between the mode step v^a..v^b and its conjugate vectors
                       v^(D+1-b)..v^(D+1-a), for every positive step of the mode rules below
                       (resolved at the newest sampled frame, as clv settles them at the first
                       frame it reads); a column of one side only is a disagreement;
  theta_min.csv        for every separation s = 1..J-1: min and mean over the sampled frames and
                       the pairs (v^j, v^(j+s)), j + s <= J, of Theta = arccos |v^i . v^j|,
                       computed as 2 arcsin(|v^i -+ v^j| / 2). J of F^(J) = v^1..v^J is the
                       paper's 370 of 393 scaled to m = 2N - 3 (round(370 m / 393)), at most m,
                       and ends before the first positive mode step (as resolved below); a table
                       with other separations than 1..J-1 is a disagreement;
  theta_histograms.csv Fig. 16: theta_lo, theta_hi = the 90 one-degree bins of [0, pi/2] (the
                       last closed), density_sep_s = count / (total * bin width) of the same Theta
                       for s in 1, 2, 4 and the paper's 20, 50, 100, 200, 300 scaled by D/792
                       (at least 1, each once, all < J); a table with other separations is a
                       disagreement. An angle within 1e-10 rad of a bin edge may lie on either
                       side of it in clv (which takes arccos of the normalised dot product,
                       good to ~1e-13 above 1e-3 rad, where it switches to the formula used
                       here): in a bin such an angle could reach, clv's count (its density
                       times total * width) must lie between the count of the angles that are
                       surely in it and that plus those that could be; the JSON's
                       theta_at_bin_edges says how many there were (none so far);
  convergence_clv.csv  t = b L tau and lambda_i = the mean of the first b batch means (below) of
                       the local CLV exponents over every frame, oldest block first;
  convergence_gs.csv   the same of the forward run's block averages in the frame file's
                       spectrum.json (the frames do not hold the forward run: this recomputes
                       the table from what clv read, it does not check those averages), with
                       t = b block_steps tau;
  convergence_tests.csv  per spectrum (0 GS, 1 CLV) with at least 4 blocks, over the exponents
                       outside the null space 2N-2..2N+3 whose block means spread (sample std)
                       beyond 1e-9 of the largest spread: tested = their number, z_i = (mean of
                       the newer half of the blocks - mean of the older half) / the hypot of the
                       two halves' standard errors (an odd count's middle block left out),
                       drifting_fraction = the share with |z| > 2, max_abs_z and its 1-based
                       max_z_index (the first of equals), h_ks_z = z of the per-block sum of
                       those with a positive sum, h_ks_chance = P(|t| > |h_ks_z|) for Student's
                       t with 2 (floor(B/2) - 1) degrees of freedom (a finite closed-form series,
                       Abramowitz & Stegun 26.7.3-4; clv uses a continued fraction; 1 where
                       h_ks_z is not finite), r1 = the lag-1 autocorrelation of the block means
                       averaged over the tested exponents, r1_limit = -1/B + 2/sqrt(B);
  spectrum.csv         also lambda_gs, stderr_gs: the forward run's spectrum, compared with the
                       frame file's spectrum.json it is copied from (not recomputable from the
                       frames: they hold only the window; with --run RUN_DIR recomputed from
                       the run's R_n instead, below); i_over_D = i / D; zero_by_symmetry = 1
                       for the null space i = 2N-2..2N+3, else 0; lambda_clv_null_shear, for
                       i = 2N+1..2N+3 (NaN elsewhere): the mean over every frame of the local
                       exponent the shear model gives those CLVs, ln(sqrt(1 + s'^2) /
                       sqrt(1 + s^2)) / tau for frame m with s = (total - m) tau, s' = s - tau,
                       total = run.json's relax_steps + steps, where the backward pass starts
                       (e_(k+3) becomes e_(k+3) - s e_k after the backward time s): the frames'
                       steps and run.json are in the frame file, and this model of the exponent
                       is what the column predicts, not a measurement (in the test's run it
                       agrees with lambda_clv there to 3e-16, 4e-14 relative).

The Lyapunov modes (modes.csv, modes.json, modes_fits.csv, modes_lp.csv, modes_dispersion.csv,
and the per-disk tables fig10_T<n>_i<i>.csv, LP<n>_i<i>.csv of Figs. 10-12) follow clv's own
rules, which are not physics but its conventions: they are re-implemented here from their
descriptions in clv's doc comments (src/stage/analyze/mode_steps.rs, modes.rs,
kernels/modes.rs), so a disagreement says the code does not do what they say. The steps are
found in the forward GS spectrum of the frame file's spectrum.json (exponents e, errors s; not
recomputable from the frames), and resolved with the vectors of one frame, the newest sampled
one (the first clv reads). Candidates: the wave vectors k = 2 pi (n_x/L_x, n_y/L_y) up to sign
with |k| <= 2 pi 4 / max(L_x, L_y) (1 + 1e-9), by |k| then falling n_x, n_y, each alone and
those of one |k| (relative 1e-9) together after them; their Table III patterns over the disks
(per wave vector [e c, e s], c, s = cos, sin(k.q_n); T: e the unit vector across k, its first
nonzero component positive, L: along k, P: the disk momentum p_n; LP = the L of every wave
vector then the P of every one) orthonormalised (QR). A group of vectors is classified by
the mean over its vectors of |P dq|^2 / |dq|^2 of their position parts (GS vectors where the
frames have them, else CLVs): the candidate with the largest fraction - dim / 2N wins (the last
of equals), and classifies clearly if (fraction - c) / (1 - c) >= 0.3, c = dim / 2N. Steps:
  - detected: walking outwards from the null space (0-based 2N-3..2N+2) on either side for
    W = max(D/16, 8, the T plus LP dimension of the smallest |k|'s largest family) indices (at
    most 2N-4), a group of one of the candidates' step lengths (longest first) is a step if it
    is a maximal run of neighbours with |e_i - e_(i+1)| <= 3 hypot(s_i, s_(i+1)), or, while
    every index walked is in a step, if its largest inner gap is below 0.1 of both gaps to its
    outer neighbours; else one index is walked;
  - a step that mirrors an earlier positive one (D - start - length) takes its resolution; a
    step classified clearly as L, P or LP but shorter than that LP mode is widened to the
    block of the LP size containing it, on its side of the null space, overlapping no other
    detected step, that stands apart (its spread e_first - e_last below both outer gaps) and
    whose LP fraction is the largest (the last of equals);
  - a step is a mode if widened, found by vectors, or classified clearly as T or as L, P,
    LP with at least the LP size; a step stays if it is a mode or in the region bordering the
    null space (the step at it, then each next one that is a mode);
  - from the null space outwards on the positive side, past the steps so far: the first block
    of a step length (longest first) that overlaps none, stands apart and is clearly the mode
    of its length (T: the T size, else the LP size), or else the first pair of lengths
    (a, b) (a outer loop) whose block of a + b stands apart and whose parts (a nearer the null
    space, then b) are each that, is added ("vectors") with its mirror where that overlaps
    none; until there is none.
modes.csv (and modes.json's rows, and the settings it lists: frames, window, candidates,
source, the thresholds), per step over the sampled frames: the votes of each frame's best
candidate; best = the most votes (the lowest candidate of equals); fraction_gs, fraction_clv
= the mean over frames of best's fraction of the GS / CLV group (NaN without); beyond_chance
= excess of fraction_gs (else fraction_clv); kind, n_x, n_y (first wave vector), k, name
only where that is >= 0.3 ("-", empty, NaN, "unclassified" otherwise); agreement = best's
votes / frames; resolved = the share of sampled frames whose own resolution of the steps
(each frame resolving them alone) has the step, with modes.json's resolved_alike (frames
whose own steps are the first frame's) and other_steps (steps only other frames find, with
their frame counts); consistent = classified with its degeneracy; lambda, spread = mean and
max - min of e over the step; detection = widened, vectors, else degenerate if every
neighbour pair is within 3 combined errors, else separated; side "+" for a step ending at
or before 2N-3. modes_fits.csv, scope mean: for the 2-steps classified T of one wave vector,
the mean over frames of the least-squares fit A cos(k x) + B sin(k x) of the components across
k of dq (and of dp) of each GS and CLV vector against its position along k x = e_k.q_n:
amp = hypot(A, B), resid = rms residual, rel_resid = resid / amp; scope "step S": the same
of the step's last vector at the shown frame S, for the positive steps classified T of one
wave vector with their degeneracy, whose components across k and wrapped positions along k
are fig10_T<n>_i<i>.csv (the CLV's sign matched to the GS vector); for a T step of several
wave vectors (T(1,0)+T(0,1) in a square box), per wave vector fig10_T<n>_i<i>.csv holds
instead the group's combination whose dq best matches that wave's cos pattern (least squares,
unit, signed as below), its components across k of dq and dp and along k of dq, and
modes_fits.csv no row. modes_lp.csv and
LP<n>_i<first>.csv: for the positive steps classified L, P or LP with their size, per wave
vector, at the shown frame, the least-squares combination of the group (GS, CLV) whose
position part (Fig. 11; momentum part, Fig. 12) best matches the raw L sin, P sin (L cos,
P cos) pattern, normalised and signed to overlap it positively: overlap = |cos| of its part
and the pattern, and the fit's amplitude, phase = atan2(-B, A) (compared modulo 2 pi) and
rms residual, of its part along k (L) or of (delta . p_n) / |p_n|^2 (P) against the wrapped
position along k. modes_dispersion.csv: the positive consistent steps by kind then k, with
stderr = the mean of s over the step and lambda_over_k. Rows match by their keys (step,
vector, source, scope, ...; the dispersion's by their order); a row or column on one side
only is a disagreement. A decision (a threshold or an argmax) within round-off of flipping
would show as a disagreement in the rows; none has been seen.

With --run RUN_DIR (the run directory of `clv forward` the frames were made from), the forward
GS spectrum is recomputed from the R_n stored in RUN_DIR's segments (read with read_run.py's
read_segment; only the diagonals are kept):
  - which steps count: `Forward::step_into` (src/stage/forward.rs:123-127) accumulates ln R_ii
    when its step counter, the steps done BEFORE this one, is >= relax_steps, then counts the
    step; the R message is logged as n = the steps done after it (src/stage/forward_run.rs:359-365,
    schemas/r.json: log_time = n). So the measured steps are n = relax_steps + 1 ..
    relax_steps + steps (run.json's config): R_(relax_steps), stored at the checkpoint that ends
    the relaxation, is not one of them, and neither is any step past the run's steps.
    lambda_i = sum of ln R_ii over them / (steps tau) (Accumulator::exponents, src/statistics.rs:80).
  - which R_n are stored: R_n at every checkpoint (every checkpoint_every steps), and with
    `--store-r all` at every step n > the window start relax_steps + steps - clv_steps - transient
    (src/stage/forward_run.rs:363-365, src/store/run.rs:124); segments ending before the window
    start are pruned (src/stage/forward_run.rs:313). All measured steps are stored only for a
    run made with --store-r all and --clv-steps + --transient = --steps (window start =
    relax_steps); for any other run the script stops and says which steps are missing (the
    checkpoints' acc_sum are clv's own sums, not used here). R_n stored twice must be the same
    bits (not seen so far: segments do not overlap).
  - blocks (stderr_gs): Accumulator::add_logs (src/statistics.rs:54-64) closes a block each time
    the count of measured steps is a multiple of the block length, counted from the FIRST
    measured step (the oldest; unlike the frames' batch means below, counted from the newest);
    the steps of the unfinished last block count in lambda, not in the error. The planned
    length is block_len(steps, blocks) = max(floor(steps / blocks), 1) (src/statistics.rs:39,
    src/stage/forward.rs:53), and limit_blocks (src/statistics.rs:70-77, called after every
    measured step, src/stage/forward.rs:125) merges neighbouring blocks pairwise, doubling the
    length, whenever 2 B or more of them are complete (B = run.json's blocks), their count even
    and no step is in an unfinished block: which happens only in a run extended past its plan
    (`clv forward --resume RUN --steps MORE`; a run that ends where it was planned never gets
    there). Here the
    plan is read from the earliest stored checkpoint taken before the first measured step
    (acc_steps = 0: its acc_block_len is what Forward::new set for the steps the run was created
    with), else taken as block_len of run.json's steps and blocks; the doubling rule is replayed
    over the measured steps, and the blocks are then consecutive runs of the final length from
    the first measured step (a merge keeps them so): n = floor(steps / length) of them. Block
    mean b of exponent i = its sum of ln R_ii over the block / (length tau)
    (Accumulator::block_averages, src/statistics.rs:86); stderr_gs = the sample std (n - 1) of
    the block means / sqrt(n) (src/statistics.rs:93-96, 160-177), NaN with n < 2. Found so:
    both agree with spectrum.json to round-off (the test's N = 8 run: lambda the same doubles,
    stderr within 2e-16 relative; a run extended from 200 to 900 steps, 20 blocks: 22 blocks of
    40 steps, not the 20 of 45 that run.json's steps alone would give, lambda the same doubles,
    stderr and block means within 3e-15), while the steps shifted by one (n = relax_steps ..
    relax_steps + steps - 1) miss lambda by 7e-3 in that N = 8 run.
  Compared (TOL for lambda, TOL_ERR for the errors): spectrum.csv lambda_gs, stderr_gs (instead
  of the frame file's copy of spectrum.json); run/spectrum.json = RUN_DIR/spectrum.json, and
  frames/spectrum.json = the frame file's copy that the report (spectrum.csv, convergence_gs.csv,
  the mode steps) was made from: exponents, stderr, blocks.block_steps (row 1) and the block
  means blocks.exponents[b] (row i, b from 0, oldest first). RUN_DIR must hold the run the
  frames were made from: its run.json config (without threads) must be the frame file's, else
  the script stops. The JSON's "forward_r" says which steps and blocks were used.

Captions (index.html): each section's caption (its <h2> title and the text of its <p>, HTML
entities undone) is searched for the phrases that state numbers, in the words of their format
strings in src/stage/analyze/*.rs, and each number is compared with the recomputation above
at the precision it is printed with: |mine - printed| <= half a unit of its last digit (plus
1e-9 |mine|: two round-offs of a number on a rounding edge may round either way). Where the
report has the section and the data call for the phrase (disks, k = D, GS vectors, ...), a
missing phrase is a disagreement, and so is a list of another length. Checked:
  Fig. 2      h_KS = the sum of the positive exponents outside the null space of the
              frames' GS and CLV spectra, with batch-means errors of the per-frame sum of
              those exponents; the whole run's (forward exponents) and its error (the
              standard error of the per-block sums of the block means: of R_n with --run,
              else of spectrum.json's blocks, else spectrum.json's ks_entropy.stderr); the
              run's steps; the null-shear phrase: s1 = (total - newest step) tau - tau,
              s2 = (total - oldest step) tau, the prediction (lambda_clv_null_shear's mean)
              and the measured lambda_clv of i = 2N+1..2N+3, in the words for consecutive
              frames or not; the sum of the whole run's GS exponents (round-off: summed
              i = 1..D one at a time from spectrum.json's doubles, as clv sums them);
  Fig. 8      the plotted range lambda_a..lambda_(2N-3), a = 2N-3 - max(D/6, 8) (at least
              1), and the medians of the errors of lambda_i and lambda_(D+1-i) over it
              (GS: the frames' steps' errors, or the whole run's without them; CLV);
  convergence each spectrum's blocks, block steps, % with |z| > 2, tested, % by chance
              (Student t, 2 (B/2 - 1) degrees of freedom), largest |z| and its i, z of h_KS
              and its chance %, r_1 and its limit (those of convergence_tests.csv, recomputed);
  Fig. 5      the sampled frames and the block length max(floor(T/B), 1) of the errors;
  Fig. 3      2N-2, and <|g^i . v^i|> at i = 2N+1..2N+3;
  Figs. 6, 7  max_i |eta_q(i) - eta_p(D+1-i)| (GS), max_i |eta_q(i) - eta_q(D+1-i)| (CLV),
              eta_q of the CLVs 2N+1..2N+3;
  Tables I, II  the frame's step and time; the first rows of beta and alpha, the maxima over
              time of the three null-space angles and the largest |alpha_(i,4..6)| of rows
              2N-2..2N: round-off mostly, not recomputable digit for digit, so against the
              report's nullspace_beta.csv, nullspace_alpha.csv, nullspace_series.csv,
              checked above to 1e-10;
  domination  the overall swap fraction at the first Delta and at the longest one that fits
              in the frames, its window count, and the verdict on E^u + E^0 + E^s (never
              violated; violated at the first Delta with its two split fractions and none
              from Delta_0 on; or still violated at the longest, with its fractions);
  Table III   the |k| bound 2 pi 4 / max(L_x, L_y); per step found (in the table's order,
              as many as rows): name, indices, degeneracy, detection, lambda, spread, fraction,
              best candidate and excess where unclassified, % of frames agreeing, frames
              resolving it; the first frame's step, the frames resolving the same steps and
              the other steps with their counts;
  Figs. 10-12 per pattern table: the frame's step and the step's indices; Fig. 10 of a pair:
              the vector shown and k = |k| (4 decimals); of several wave vectors: k and the
              |cos| of each source's reconstructed dq with the pattern; Figs. 11-12: the rms
              of L's check component over its component along k (from the Fig. 11 columns),
              and for each of the four figures whether points lie off its scale, how many of
              how many, and the range (5th and 95th percentiles of the finite values, at least
              20, widened by their distance on either side);
  dispersion  per kind the least-squares slope through the origin sum(lambda k)/sum(k^2),
              its error sqrt(sum of squared residuals / (m - 1) / sum(k^2)) where there are
              m >= 2 steps (and none printed with one), its number of steps and lambda/k of each;
  Fig. 14     for the last vector j of each positive mode step (where there are two or
              more: with fewer clv shows j = 2N-5, 2N-3 and says nothing of it), the largest <|v^j . v^i|>
              (i != j) inside its step, inside the conjugate step and elsewhere;
  Fig. 15     E^u, E^s, min and mean of Psi (degrees and radians), "Psi > 0" where it is, and
              min and mean of Phi of each positive mode step (by its indices);
  Fig. 16     J, the separations, the density of i - j = 1 in the first bin and the mean of
              the next four, and the verdict (too few angles, with their count; falls; dips,
              with its %; does not fall) - skipped if an angle lies at an edge of those bins;
  Fig. 17     J, the frames and min Theta of i - j = 1.
A disagreement is one line: "disagreement: caption 'TITLE' WHAT mine X caption Y", or
"...: no phrase like '...'" (X for a number). The JSON's "captions" lists what was
checked per caption.
Not checked: the notes of modes.json and nullspace_tables.json (fixed texts); summary.json
and the report's head paragraphs; the captions' words that restate settings or selections
(the indices of Figs. 4, 13 and of the local and finite-time exponents, the candidates'
list, the Deltas) and their verdict sentences beyond those above (the convergence verdict
and its AR(1) factor, Fig. 14's order of the paper); Fig. 15's median angle between random
subspaces (clv's own random draw);
the captions of non-disk systems (this script reads hard-disk reports only).

Sampling: the spectrum, the local and finite-time exponents, domination and convergence use
every frame of the file; the vector statistics (modes, the null space, Psi, Phi and Theta
too) use the frames
of the steps that are multiples of m = summary.json's options.every that carry vectors (as
the report says in its head). Frames are put in step order whatever the file's order. Tables
(and _std / stderr columns) the report does not have are skipped.

Batch means (stderr columns): B = the run's `blocks` setting, read from run.json in the
frame file's metadata (summary.json does not hold it; --blocks overrides). Of T frames (all
of them for the spectrum, the sampled ones for localization) blocks of L = max(floor(T / B), 1)
frames are counted from the NEWEST frame, as many as fit: n = floor(T / L) blocks, which is
B when L > 1 and T < B (L + 1) but more otherwise (43 sampled frames, B = 20: 21 blocks of 2;
71 frames: 23 blocks of 3). This was found by trying alternatives against the CSVs: exactly
B blocks of L (leaving T - B L frames out) misses by up to 13 %, blocks counted from the
oldest frame by 19-34 %, std with n instead of n - 1 by 2.5 %; the rule above agrees to
~1e-15 relative. The oldest T mod L frames count in the means, not in the errors. The error
is the sample std (n - 1) of the block means / sqrt(n); NaN with n < 2.

Tolerance: round-off. A value agrees when |mine - report| <= 1e-10 max(1, |report|) (the
quantities are averages of O(1) numbers; the report writes them with all digits); NaN only
against NaN; text cells (names, kinds, indices of modes) must be equal. The same bound holds
for the mode fractions, fits and least-squares reconstructions (sums over 2N disks of
products of O(1) numbers, and 2 x 2 or 2N x 4 least-squares problems of well separated
singular values: ~1e-14 seen), the t-distribution chance (two methods for it agree to
~1e-14) and the histogram densities (ratios of integer counts). A stderr agrees when
|mine - report| <= 1e-9 |report| or <= 1e-15 (the errors of exactly vanishing exponents are
round-off, ~1e-16). A _std agrees when |mine - report| <=
1e-9 |report| or <= 1e-12 (the spread of a constant, |v^i . v^i| = 1, is round-off). Until
2026-11-27 clv summed x and x^2 over the frames, and its _std of a constant came out ~1e-8
= sqrt(1e-16) instead of 0; this check found it. Also until 2026-11-27, clv's
lambda_clv_null_shear was the model's time average over the whole span of the frames' steps,
which is the mean over the frames only where they are consecutive: for a file of every third
step it was -6.11915e-3 against the -6.12782e-3 of the frames it holds (and of their
lambda_clv); this check found that too.
The JSON on stdout: {"agree": ..., "checked": {table: largest |mine - report| over its mean
and stderr columns}, "checked_std": {table: the same over its _std columns}, "columns":
{table: [columns compared]}, "frames": n, "sampled": n, "every": m, "blocks": B,
"mode_steps": [[first, last, how found]], "theta_j": J, "theta_at_bin_edges": n, ...}, with
--run also "forward_r": {"steps": [first n, last n], "block_steps": final length,
"planned_block_steps", "plan_from": "checkpoint" or "run.json", "blocks": their number}.
A disagreement is one line on stderr: "disagreement: TABLE COLUMN ROW [(what the row is)]
mine X report Y", ROW the index i, step, separation or bin where the table has one, else the
row's number in the file (from 1).

Only the physics and the report's conventions (file layout, columns, the ordering
(dq_x1, dq_y1, ..., dq_yN, dp_x1, ..., dp_yN), 1-based indices, and the mode rules above as
clv's doc comments state them, with what they leave open read from its code: the order in
which lengths and pairs are tried, which of equals wins, the 1e-9 of equal |k|, the cap of
the walk at 2N-4 indices) are shared with clv; the code is not: the numpy here is written
from those descriptions, not translated from clv's Rust.
"""
import argparse
import collections
import csv
import glob
import html
import json
import math
import os
import re
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from read_frames import load_frames, metadata, run_json  # noqa: E402
from read_run import read_segment  # noqa: E402

TOL = 1e-10
TOL_ERR = 1e-9
ROUND_OFF_SQ = 1e-24


def read_csv(path):
    """Columns of a CSV file as float arrays (None if the file is absent)."""
    if not os.path.exists(path):
        return None
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]} if rows else {}


def read_rows(path):
    """Rows of a CSV file as dicts of their cells as written (None if the file is absent)."""
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return list(csv.DictReader(f))


def batch_stderr(x, blocks):
    """Batch-means standard error of the mean over axis 0 of x (rows in increasing step order).

    Blocks of L = floor(T / blocks) rows (at least 1), as many as fit (n = floor(T / L),
    which can exceed blocks: 43 rows, 20 blocks -> 21 blocks of 2), counted from the newest
    row; the oldest T mod L rows fill no block and are left out. The error is the sample
    std (n - 1) of the block means over sqrt(n); NaN with n < 2.
    """
    x = np.asarray(x, float)
    t = x.shape[0]
    length = max(t // blocks, 1)
    count = t // length
    if count < 2:
        return np.full(x.shape[1:], np.nan)
    means = x[t - count * length :].reshape((count, length) + x.shape[1:]).mean(axis=1)
    return means.std(axis=0, ddof=1) / np.sqrt(count)


def sample_std(x):
    """Sample standard deviation (n - 1) over axis 0; NaN with fewer than two rows."""
    x = np.asarray(x, float)
    return x.std(axis=0, ddof=1) if x.shape[0] > 1 else np.full(x.shape[1:], np.nan)


class Checker:
    def __init__(self):
        self.checked, self.checked_std, self.columns, self.bad = {}, {}, {}, []

    def compare_std(self, table, column, index, x, report):
        """A _std column: mine = sample_std(x) over axis 0 of x (frames, rows).

        Agrees if |mine - report| <= TOL_ERR |report| or <= 1e-12 (the spread of a constant
        is round-off). The worst |mine - report| goes to checked_std."""
        mine, report = sample_std(x)[index - 1], np.asarray(report, float)
        worst = self.checked_std.get(table, 0.0)
        self.columns.setdefault(table, []).append(column)
        for idx, m, r in zip(np.ravel(index), mine, report):
            if np.isnan(m) or np.isnan(r):
                ok = np.isnan(m) and np.isnan(r)
            else:
                worst = max(worst, abs(m - r))
                ok = abs(m - r) <= TOL_ERR * abs(r) or abs(m - r) <= 1e-12
            if not ok:
                self.bad.append(f"disagreement: {table} {column} {int(idx)} mine {float(m)!r} report {float(r)!r}")
        self.checked_std[table] = float(worst)

    def compare(self, table, column, index, mine, report, tol=TOL):
        """Compare mine with report element by element; index labels the rows.

        tol is relative: |mine - report| <= tol max(1, |report|), or for errors (tol =
        TOL_ERR) <= tol |report| with an absolute floor of 1e-15 (errors of exactly
        constant columns are round-off, ~1e-16)."""
        mine, report = np.broadcast_to(np.asarray(mine, float), np.shape(report)), np.asarray(report, float)
        worst = self.checked.get(table, 0.0)
        self.columns.setdefault(table, []).append(column)
        for idx, x, y in zip(np.ravel(index), np.ravel(mine), np.ravel(report)):
            if np.isnan(x) or np.isnan(y):
                ok = np.isnan(x) and np.isnan(y)
            else:
                worst = max(worst, abs(x - y))
                bound = TOL * max(1.0, abs(y)) if tol == TOL else max(tol * abs(y), 1e-15)
                ok = abs(x - y) <= bound
            if not ok:
                self.bad.append(f"disagreement: {table} {column} {int(idx)} mine {float(x)!r} report {float(y)!r}")
        self.checked[table] = float(worst)

    def expect_keys(self, table, got, expected):
        """The table's rows, named by their key cells (`got`, in file order), must be
        `expected` exactly: a row deleted, repeated or renumbered is a disagreement."""
        got, expected = [tuple(np.atleast_1d(k).tolist()) for k in got], [tuple(np.atleast_1d(k).tolist()) for k in expected]
        if got == expected:
            return
        have, want = collections.Counter(got), set(expected)
        missing = [k for k in expected if k not in have]
        extra = [k for k in got if k not in want]
        repeated = sorted(k for k, count in have.items() if count > 1)
        what = "; ".join(f"{name} {ks[:5]}" for name, ks in (("missing", missing), ("not expected", extra), ("repeated", repeated)) if ks) or "out of order"
        self.bad.append(f"disagreement: {table} rows: {what} ({len(got)} rows, {len(expected)} expected)")

    def expect_columns(self, table, header, keys):
        """Every column of the table is a key or was compared: one nothing here recomputes
        is a disagreement."""
        for col in header:
            if col not in keys and col not in self.columns.get(table, []):
                self.bad.append(f"disagreement: {table} column {col} is not recomputed here")

    def compare_rows(self, table, keys, mine, report, label, tol=TOL):
        """Rows of a table with text cells: each report row (numbered from 1 in the file) is
        matched with mine by its `keys` cells; text cells must be equal, numbers agree as in
        compare (tol; NaN, or an empty cell, only against NaN). A row or a column of the
        report that is not recomputed here, or a row of mine the report lacks, is a
        disagreement. label(row) names the row in messages."""
        worst = self.checked.get(table, 0.0)
        self.columns.setdefault(table, [])
        index = {tuple(str(m[k]) for k in keys): m for m in mine}
        seen = set()
        for r, row in enumerate(report, 1):
            key = tuple(row[k] for k in keys)
            m = index.get(key)
            if m is None:
                self.bad.append(f"disagreement: {table} row {r} ({label(row)}) is not recomputed here")
                continue
            seen.add(key)
            for col, y in row.items():
                if col in keys:
                    continue
                if col not in m:
                    self.bad.append(f"disagreement: {table} column {col} is not recomputed here")
                    continue
                if col not in self.columns[table]:
                    self.columns[table].append(col)
                x = m[col]
                if isinstance(x, str):
                    ok = x == y
                else:
                    x, y = float(x), float(y) if y != "" else math.nan
                    if math.isnan(x) or math.isnan(y):
                        ok = math.isnan(x) and math.isnan(y)
                    else:
                        worst = max(worst, abs(x - y))
                        ok = abs(x - y) <= tol * max(1.0, abs(y))
                if not ok:
                    self.bad.append(f"disagreement: {table} {col} {r} ({label(row)}) mine {x!r} report {y!r}")
        for key, m in index.items():
            if key not in seen:
                self.bad.append(f"disagreement: {table} lacks a row mine has ({label(m)})")
        self.checked[table] = float(worst)


def disk_weights(x, n):
    """mu_n: |x|^2 on disk n's four components, per frame and vector: (T, N, k)."""
    dq, dp = x[:, : 2 * n], x[:, 2 * n :]
    return dq[:, 0::2] ** 2 + dq[:, 1::2] ** 2 + dp[:, 0::2] ** 2 + dp[:, 1::2] ** 2


def localization(x, n, blocks):
    """W = exp(<S>) / N and its error W * batch_stderr(S)."""
    mu = disk_weights(x, n)
    mu = mu / mu.sum(axis=1, keepdims=True)
    terms = np.where(mu > 0, mu * np.log(np.where(mu > 0, mu, 1.0)), 0.0)
    entropy = -terms.sum(axis=1)
    w = np.exp(entropy.mean(axis=0)) / n
    return w, w * batch_stderr(entropy, blocks)


def projections(x, n):
    dq, dp = x[:, : 2 * n], x[:, 2 * n :]
    eq, ep = (dq**2).sum(axis=1), (dp**2).sum(axis=1)
    has_theta = np.minimum(eq, ep) >= ROUND_OFF_SQ
    cos = np.where(has_theta, (dq * dp).sum(axis=1) / np.sqrt(np.where(has_theta, eq * ep, 1.0)), 0.0)
    count = has_theta.sum(axis=0)
    mean_cos = np.where(count > 0, cos.sum(axis=0) / np.maximum(count, 1), np.nan)
    return {"eta_q": eq.mean(axis=0), "eta_p": ep.mean(axis=0), "cos_theta": mean_cos}, {"eta_q": eq, "eta_p": ep}


def windows(local, delta):
    """Finite-time exponents: means of local over consecutive windows of delta frames, counted
    from the newest frame (the oldest T mod delta frames fill no window): (W, k).

    Each window is summed one frame at a time from its newest frame, then divided by delta:
    the null-space exponents vanish, their differences are round-off, and whether such a pair
    swaps in domination.csv depends on the order of summation (numpy's mean missed one swap
    of 1860 at delta = 5 in the test's run; this order matches all)."""
    return window_sums(local, delta) / delta


def window_sums(local, delta):
    """The sums of local over the windows of `windows`, in its order. The domination test
    compares these, as clv does: dividing two sums an ulp apart by delta can round them to
    one mean (the paper's run: one window of 5000 at delta = 5 for the null-space pair
    398/399, whose shear exponents are equal to round-off)."""
    t = local.shape[0]
    count = t // delta
    x = local[t - count * delta :].reshape((count, delta) + local.shape[1:])
    total = np.zeros((count,) + local.shape[1:])
    for k in range(delta - 1, -1, -1):
        total = total + x[:, k]
    return total


def domination(x, n):
    """Swap fractions of the finite-time exponents of N disks, given as their window sums x
    (W windows, k; `window_sums`).

    A pair (i, i + 1) swaps in a window where exponent i + 1 exceeds exponent i. overall:
    mean over all windows and pairs; outside_null: the same over the pairs not both inside
    the null space 2N-2..2N+3 (the two that straddle its borders count); pair_i_j: one pair;
    border_unstable_null, border_null_stable: the pairs (2N-3, 2N-2), (2N+3, 2N+4);
    split_unstable_null (split_null_stable): the fraction of windows in which some exponent
    of 1..2N-3 lies below some exponent of 2N-2..2N+3 (some of the null space below some of
    2N+4..D)."""
    k = x.shape[1]
    swap = x[:, 1:] > x[:, :-1]  # column a - 1: the pair (a, a + 1)
    lo, hi = 2 * n - 2, 2 * n + 3  # the null space, 1-based
    out = [a - 1 for a in range(1, k) if not (lo <= a and a + 1 <= hi)]
    result = {"windows": x.shape[0], "overall": swap.mean(), "outside_null": swap[:, out].mean()}
    for a in range(1, k):
        result[f"pair_{a}_{a + 1}"] = swap[:, a - 1].mean()
    if hi < k:
        result["border_unstable_null"] = swap[:, lo - 2].mean()
        result["border_null_stable"] = swap[:, hi - 1].mean()
        result["split_unstable_null"] = np.mean(x[:, : lo - 1].min(axis=1) < x[:, lo - 1 : hi].max(axis=1))
        result["split_null_stable"] = np.mean(x[:, lo - 1 : hi].min(axis=1) < x[:, hi:].max(axis=1))
    return result


def natural_basis(phase, n):
    """e_1..e_6 of the null space as columns (D, 6)."""
    d = 4 * n
    p = phase[2 * n :]
    e = np.zeros((d, 6))
    e[: 2 * n, 0] = e[2 * n :, 3] = p / np.linalg.norm(p)
    e[0 : 2 * n : 2, 1] = e[1 : 2 * n : 2, 2] = 1 / np.sqrt(n)
    e[2 * n :: 2, 4] = e[2 * n + 1 :: 2, 5] = 1 / np.sqrt(n)
    return e


def span_basis(x):
    """An orthonormal basis of the column span of x (D, k), full column rank assumed: the
    left singular vectors of its thin SVD (clv takes a QR)."""
    return np.linalg.svd(x, full_matrices=False)[0]


def principal_angle_range(a, b):
    """(smallest, largest) principal angle between span(a) and span(b), columns (D, ka), (D, kb).

    With orthonormal bases Q_a of the smaller span and Q_b: the singular values of Q_a^T Q_b
    are the cosines of the min(ka, kb) angles, those of Q_a - Q_b Q_b^T Q_a their sines; the
    largest cosine and the smallest sine belong to the smallest angle, the smallest cosine and
    the largest sine to the largest. Each angle is atan2(sine, cosine), accurate at 0 and at
    pi/2 alike (clv takes asin of the sine below pi/4, else acos of the cosine)."""
    qa, qb = span_basis(a), span_basis(b)
    if qa.shape[1] > qb.shape[1]:
        qa, qb = qb, qa
    cos = np.linalg.svd(qa.T @ qb, compute_uv=False)
    sin = np.linalg.svd(qa - qb @ (qb.T @ qa), compute_uv=False)
    return math.atan2(sin.min(), cos.max()), math.atan2(sin.max(), cos.min())


def null_shear_mean(steps, total, tau):
    """The mean over the frames of `steps` of the local exponent the shear model gives the last
    three null-space CLVs (spectrum.csv's lambda_clv_null_shear).

    The backward pass starts at the run's end, step `total`; at the backward time s the CLV
    is along e_(k+3) - s e_k (a free flight in the null space moves the positions by t times
    the momentum direction: D phi^t e_(k+3) = e_(k+3) + t e_k, and e_k, e_(k+3) are
    orthonormal), of norm sqrt(1 + s^2) against e_(k+3). Frame m's vector, at s = (total - m)
    tau, is carried over [t_m, t_(m+1)] to s' = s - tau: its local exponent is
    ln(sqrt(1 + s'^2) / sqrt(1 + s^2)) / tau. Each frame's is computed and averaged, as
    lambda_clv averages the frames' local exponents, whatever steps the file holds."""
    s = (total - np.asarray(steps, float)) * tau
    return float(np.mean((np.log1p((s - tau) ** 2) - np.log1p(s**2)) / (2 * tau)))



# ---------------------------------------------------------------------------------------
# Lyapunov modes (paper Sec. 5.5, Table III): modes.csv, modes.json, modes_fits.csv,
# modes_lp.csv, modes_dispersion.csv and the per-disk pattern tables of Figs. 10-12.

MAX_N = 4  # candidate wave vectors: |k| <= 2 pi MAX_N / max(L_x, L_y)
MIN_FRACTION = 0.3  # least share beyond chance that classifies a step
STEP_TOL = 3.0  # neighbours within this many combined standard errors are degenerate
SEPARATION = 0.1  # a group whose spread is below this fraction of both outer gaps is a step
KINDS = ("T", "L", "P", "LP")


def wave_k(w, lx, ly):
    return (math.tau * w[0] / lx, math.tau * w[1] / ly)


def wave_norm(w, lx, ly):
    return math.hypot(*wave_k(w, lx, ly))


def wave_axes(w, lx, ly):
    """Unit vectors along k and across it (first nonzero component of the latter positive)."""
    kx, ky = wave_k(w, lx, ly)
    k = math.hypot(kx, ky)
    along = (kx / k, ky / k)
    across = (along[1], 0.0 - along[0]) if along[1] > 0 else (0.0 - along[1], along[0])
    return along, across


def mode_candidates(lx, ly):
    """The candidate families [(waves, |k|)]: every wave vector k = 2 pi (n_x/L_x, n_y/L_y) up
    to sign with |k| <= 2 pi MAX_N / max(L_x, L_y), by |k| (falling n_x, n_y within one |k|),
    each alone, and those of one |k| together after the last of them."""
    k_max = math.tau * MAX_N / max(lx, ly) * (1 + 1e-9)
    nx_max, ny_max = int(k_max * lx / math.tau), int(k_max * ly / math.tau)
    waves = [(a, b) for a in range(nx_max + 1) for b in range(-ny_max, ny_max + 1) if (a > 0 or b > 0) and wave_norm((a, b), lx, ly) <= k_max]
    waves.sort(key=lambda w: (wave_norm(w, lx, ly), -w[0], -w[1]))
    families, shell = [], []
    for i, w in enumerate(waves):
        k = wave_norm(w, lx, ly)
        families.append(([w], k))
        shell.append(w)
        next_k = wave_norm(waves[i + 1], lx, ly) if i + 1 < len(waves) else math.inf
        if next_k - k > 1e-9 * k:
            if len(shell) > 1:
                families.append((list(shell), wave_norm(shell[0], lx, ly)))
            shell = []
    return families


def mode_dim(kind, family):
    return (4 if kind == "LP" else 2) * len(family[0])


def mode_name(kind, family):
    return "+".join(f"{kind}({a},{b})" for a, b in family[0])


def mode_patterns(kind, family, phase, lx, ly):
    """Table III patterns (2N, dim): per wave vector [e c, e s] (T: e across k, L: e along k,
    P: the disk momenta), c, s = cos, sin(k . q_n); LP = [L of every wave, P of every wave]."""
    if kind == "LP":
        return np.hstack([mode_patterns("L", family, phase, lx, ly), mode_patterns("P", family, phase, lx, ly)])
    n = phase.size // 4
    q, p = phase[: 2 * n].reshape(n, 2), phase[2 * n :].reshape(n, 2)
    cols = []
    for w in family[0]:
        kx, ky = wave_k(w, lx, ly)
        along, across = wave_axes(w, lx, ly)
        arg = kx * q[:, 0] + ky * q[:, 1]
        for f in (np.cos(arg), np.sin(arg)):
            e = p if kind == "P" else np.array(across if kind == "T" else along)[None, :]
            cols.append((e * f[:, None]).ravel())
    return np.array(cols).T


class ModeFrame:
    """One frame's orthonormalised Table III bases of every candidate (family-major, kinds
    T, L, P, LP: candidate index 4 f + kind) and the fractions of vector groups in them."""

    def __init__(self, frame, families, lx, ly):
        self.frame, self.families, self.n = frame, families, frame["phase"].size // 4
        self.bases = [np.linalg.qr(mode_patterns(kind, fam, frame["phase"], lx, ly))[0] for fam in families for kind in KINDS]
        self.dims = np.array([mode_dim(kind, fam) for fam in families for kind in KINDS])
        self.cache = {}

    def fractions(self, x, start, length):
        """Mean over the vectors x[:, start:start+length] of |P dq|^2 / |dq|^2 in every
        candidate's span (NaN where no vector has a nonzero position part)."""
        dq = x[: 2 * self.n, start : start + length]
        xx = (dq**2).sum(axis=0)
        ok = np.isfinite(xx) & (xx > 0)
        out = []
        for q in self.bases:
            fr = ((q.T @ dq) ** 2).sum(axis=0)[ok] / xx[ok]
            fr = fr[np.isfinite(fr)]
            out.append(fr.mean() if fr.size else np.nan)
        return np.array(out)

    def classifying(self):
        return self.frame["g"] if self.frame["g"] is not None else self.frame["v"]

    def classify(self, start, length):
        """The best candidate of the classifying set's group (GS vectors, else CLVs): the
        largest fraction beyond its chance dim / 2N (the last of equals); (c, fraction) or None."""
        key = (start, length)
        if key not in self.cache:
            fr = self.fractions(self.classifying(), start, length)
            score = np.where(np.isfinite(fr), fr - self.dims / (2 * self.n), -np.inf)
            finite = np.flatnonzero(np.isfinite(fr))
            c = None if not finite.size else int(finite[np.flatnonzero(score[finite] == score[finite].max())[-1]])
            self.cache[key] = (c, fr)
        c, fr = self.cache[key]
        return None if c is None else (c, fr[c])

    def clearly(self, start, length):
        """classify, where its fraction is at least MIN_FRACTION beyond chance."""
        m = self.classify(start, length)
        if m is None or not excess(m[1], self.dims[m[0]], 4 * self.n) >= MIN_FRACTION:
            return None
        return m


def excess(fraction, dim, d):
    """(fraction - c) / (1 - c), c = dim / (D/2) a random vector's share; NaN where c >= 1."""
    chance = dim / (d // 2)
    return np.nan if chance >= 1 else (fraction - chance) / (1 - chance)


def matches_degeneracy(length, c, families):
    kind, fam = KINDS[c % 4], families[c // 4]
    return length == mode_dim("T" if kind == "T" else "LP", fam)


def joined(e, s, i, tol=STEP_TOL):
    return abs(e[i] - e[i + 1]) <= tol * math.hypot(s[i], s[i + 1])


def detect_steps(e, s, window, lengths):
    """The candidate steps of the forward GS spectrum e (errors s) next to the null space (the
    0-based indices 2N-3..2N+2), walking outwards on either side for up to `window` indices:
    a group of one of `lengths` (longest first) is a step where it is a maximal run of
    neighbours equal within STEP_TOL combined errors, or, as long as every index walked so
    far is in a step, where its largest inner neighbour gap is below SEPARATION times both
    gaps to its outer neighbours. [(start, length)], 0-based, in index order."""
    d = len(e)
    null_lo, null_hi = d // 2 - 3, d // 2 + 3
    window = min(window, null_lo - 1)
    runs, start = set(), 0
    for i in range(d):
        if i + 1 == d or not joined(e, s, i):
            if i + 1 - start >= 2:
                runs.add((start, i + 1 - start))
            start = i + 1
    gap = lambda i: abs(e[i] - e[i + 1])  # noqa: E731

    def is_step(start, length, contiguous):
        inner = [gap(i) for i in range(start, start + length - 1) if not math.isnan(gap(i))]
        spread = max(inner, default=0.0)
        separated = contiguous and math.isfinite(spread) and all(spread < SEPARATION * gap(i) for i in (start - 1, start + length - 1))
        return (start, length) in runs or separated

    steps = []
    for positive in (True, False):
        walked, contiguous = 0, True
        while walked < window:
            at = lambda length: null_lo - walked - length if positive else null_hi + walked  # noqa: E731
            length = next((L for L in lengths if L >= 2 and walked + L <= window and is_step(at(L), L, contiguous)), None)
            if length is None:
                walked, contiguous = walked + 1, False
            else:
                steps.append((at(length), length))
                walked += length
    return sorted(steps)


def resolve_steps(detected, mf, e, families, lengths):
    """The mode steps, fixed at one frame mf (ModeFrame), from the detected steps (see the
    docstring at the top: widened, pruned, found by their vectors). [((start, length), how)]
    with how in "exponents", "widened", "vectors", in index order."""
    d = len(e)
    null_lo, null_hi = d // 2 - 3, d // 2 + 3
    positive = lambda st: st[0] + st[1] <= null_lo  # noqa: E731
    mirror = lambda st: (d - st[0] - st[1], st[1])  # noqa: E731
    apart = lambda a, b: a[0] >= b[0] + b[1] or b[0] >= a[0] + a[1]  # noqa: E731

    def stands_apart(st):
        a, b = st[0], st[0] + st[1] - 1
        spread = abs(e[a] - e[b])
        return a > 0 and b + 1 < d and spread < abs(e[a - 1] - e[a]) and spread < abs(e[b] - e[b + 1])

    out = []
    for i, st in enumerate(detected):
        partner = next((j for j, o in enumerate(detected) if positive(o) and not positive(st) and mirror(o) == st), None)
        if partner is not None and partner < len(out):
            out.append((mirror(out[partner][0]), out[partner][1]))
            continue
        widened = None
        m = mf.clearly(*st)
        if m is not None and KINDS[m[0] % 4] != "T" and st[1] < mode_dim("LP", families[m[0] // 4]):
            f = m[0] // 4
            length = mode_dim("LP", families[f])
            best = None
            for start in range(max(st[0] + st[1] - length, 0), st[0] + 1):
                c = (start, length)
                side = start + length <= null_lo or start >= null_hi
                if start + length > d or not side or not all(j == i or apart(c, o) for j, o in enumerate(detected)) or not stands_apart(c):
                    continue
                lp = mf.fractions(mf.classifying(), start, length)[4 * f + 3]
                if np.isfinite(lp) and (best is None or lp >= best[1]):
                    best = (c, lp)
            widened = best and best[0]
        out.append((widened, "widened") if widened else (st, "exponents"))

    def is_mode(item):
        st, how = item
        m = mf.clearly(*st)
        return how != "exponents" or (m is not None and (KINDS[m[0] % 4] == "T" or st[1] >= mode_dim("LP", families[m[0] // 4])))

    # The mode region bordering the null space: the step at it and each next one that is a mode.
    keep = [False] * len(out)
    for edge, outward in ((null_lo, -1), (null_hi, 1)):
        end = edge
        while True:
            i = next((i for i, (st, _) in enumerate(out) if (st[0] + st[1] if outward < 0 else st[0]) == end), None)
            if i is None or not (end == edge or is_mode(out[i])):
                break
            keep[i] = True
            end = out[i][0][0] if outward < 0 else out[i][0][0] + out[i][0][1]
    out = [item for item, k in zip(out, keep) if k or is_mode(item)]

    def is_that_mode(st):
        m = mf.clearly(*st)
        return m is not None and matches_degeneracy(st[1], m[0], families)

    edge = null_lo
    while True:
        below = next((st for st, _ in out if st[0] + st[1] == edge and positive(st)), None)
        if below is not None:
            edge = below[0]
            continue
        clear = lambda c: all(apart(c, o) for o, _ in out)  # noqa: E731
        parts = next(([(edge - L, L)] for L in lengths if L < edge and clear((edge - L, L)) and stands_apart((edge - L, L)) and is_that_mode((edge - L, L))), None)
        if parts is None:
            for a in lengths:
                for b in lengths:
                    whole, inner, outer = (edge - a - b, a + b), (edge - a, a), (edge - a - b, b)
                    if a + b < edge and clear(whole) and stands_apart(whole) and is_that_mode(inner) and is_that_mode(outer):
                        parts = [inner, outer]
                        break
                if parts:
                    break
        if not parts:
            break
        for c in parts:
            out.append((c, "vectors"))
            if all(apart(mirror(c), o) for o, _ in out):
                out.append((mirror(c), "vectors"))
            edge = c[0]
    return sorted(out)


def fit_sine(x, y, k):
    """Least squares y ~ A cos(k x) + B sin(k x): (amplitude, phase = atan2(-B, A), rms
    residual), NaN from fewer than two finite points or singular normal equations."""
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 2:
        return (np.nan,) * 3
    m = np.stack([np.cos(k * x), np.sin(k * x)], axis=1)
    gram = m.T @ m
    if abs(np.linalg.det(gram)) <= 1e-12 * gram.diagonal().max() ** 2:
        return (np.nan,) * 3
    (a, b), *_ = np.linalg.lstsq(m, y, rcond=None)
    return (math.hypot(a, b), math.atan2(-b, a), float(np.sqrt(np.mean((y - m @ (a, b)) ** 2))))


def across_fits(v, phase, w, lx, ly):
    """Sine fits of dq and dp across k against the position along k (unwrapped): (q fit, p fit)."""
    n = phase.size // 4
    along, across = wave_axes(w, lx, ly)
    x = phase[: 2 * n].reshape(n, 2) @ np.array(along)
    k = wave_norm(w, lx, ly)
    return tuple(fit_sine(x, part.reshape(n, 2) @ np.array(across), k) for part in (v[: 2 * n], v[2 * n :]))


def fit_values(q, p):
    """amp, resid, resid/amp of the dq fit and of the dp fit (the columns of modes_fits.csv)."""
    return [q[0], q[2], q[2] / q[0], p[0], p[2], p[2] / p[0]]


def pattern_axes(w, lx, ly):
    """Position along k wrapped into the span over which the pattern repeats, its column name,
    and the names of the components along and across k."""
    k = wave_norm(w, lx, ly)
    if w[1] == 0:
        return lx, "q_x", "x", "y"
    if w[0] == 0:
        return ly, "q_y", "y", "x"
    return math.tau * math.gcd(*w) / k, "e_k·q", "k", "t"


def mode_tables(sampled, first, spectrum, lx, ly, d):
    """The mode tables recomputed from the sampled frames (first: the frame the steps are
    resolved at and the patterns drawn from) and the forward spectrum: ({file: [row dicts]}
    for modes.csv (its rows are also modes.json's; "modes.json" holds the settings it lists),
    modes_fits.csv, modes_lp.csv, modes_dispersion.csv, and "patterns": {file: {column:
    values per disk}}; the resolved steps [((start, length), how)])."""
    n = d // 4
    families = mode_candidates(lx, ly)
    e = np.asarray(spectrum["exponents"], float)
    s = np.array([np.nan if x is None else x for x in spectrum["stderr"]], float)
    lengths = sorted({mode_dim(kind, f) for f in families for kind in ("T", "LP")}, reverse=True)
    k_min = families[0][1]
    window = max(d // 16, 8, max(mode_dim("T", f) + mode_dim("LP", f) for f in families if f[1] == k_min))
    shown = ModeFrame(first, families, lx, ly)
    detected = detect_steps(e, s, window, lengths)
    steps = resolve_steps(detected, shown, e, families, lengths)
    ncand = 4 * len(families)
    # Every sampled frame resolves the steps again on its own: how many give the first
    # frame's steps (modes.json's resolved_alike), how many find each step (resolved,
    # other_steps).
    alike, found = 0, {}
    acc = {st: {"votes": np.zeros(ncand, int), "gs": [], "clv": [], "fits": []} for st, _ in steps}
    for f in sampled:
        mf = shown if f is first else ModeFrame(f, families, lx, ly)
        own = [st for st, _ in resolve_steps(detected, mf, e, families, lengths)]
        alike += own == [st for st, _ in steps]
        for st in own:
            found[st] = found.get(st, 0) + 1
        for st, _ in steps:
            a = acc[st]
            m = mf.classify(*st)
            if m is not None:
                a["votes"][m[0]] += 1
            a["clv"].append(mf.fractions(f["v"], *st))
            if f["g"] is not None:
                a["gs"].append(mf.fractions(f["g"], *st))
            if st[1] == 2:
                a["fits"].append([[fit_values(*across_fits(x[:, st[0] + j], f["phase"], fam[0][0], lx, ly)) if x is not None and len(fam[0]) == 1 else [np.nan] * 6 for fam in families] for x in (f["g"], f["v"]) for j in range(2)])
    frames_used = len(sampled)
    rows, chosen = [], []
    for st, how in steps:
        a = acc[st]
        votes = a["votes"]
        best = None if votes.max(initial=0) == 0 else int(np.flatnonzero(votes == votes.max())[0])
        gs = np.mean(a["gs"], axis=0) if a["gs"] else None
        clv = np.mean(a["clv"], axis=0) if a["clv"] else None
        pick = lambda m: None if best is None or m is None or not np.isfinite(m[best]) else float(m[best])  # noqa: E731
        fraction = pick(gs) if pick(gs) is not None else pick(clv)
        fam = None if best is None else families[best // 4]
        kind = None if best is None else KINDS[best % 4]
        beyond = np.nan if fraction is None else excess(fraction, mode_dim(kind, fam), d)
        clear = beyond >= MIN_FRACTION
        chosen.append(best if clear else None)
        vals = e[st[0] : st[0] + st[1]]
        if how == "exponents":
            how = "degenerate" if all(joined(e, s, i) for i in range(st[0], st[0] + st[1] - 1)) else "separated"
        rows.append({
            "side": "+" if st[0] + st[1] <= d // 2 - 3 else "-", "first": str(st[0] + 1), "last": str(st[0] + st[1]),
            "degeneracy": str(st[1]), "detection": how, "lambda": vals.sum() / st[1], "spread": vals.max() - vals.min(),
            "kind": kind if clear else "-", "n_x": str(fam[0][0][0]) if clear else "", "n_y": str(fam[0][0][1]) if clear else "",
            "k": fam[1] if clear else np.nan, "name": mode_name(kind, fam) if clear else "unclassified",
            "best": "-" if best is None else mode_name(kind, fam), "beyond_chance": beyond,
            "fraction_gs": np.nan if pick(gs) is None else pick(gs), "fraction_clv": np.nan if pick(clv) is None else pick(clv),
            "agreement": 0.0 if best is None else votes[best] / max(frames_used, 1),
            "resolved": found.get(st, 0) / max(frames_used, 1),
            "consistent": str(bool(clear and matches_degeneracy(st[1], best, families))).lower(), "frames": str(frames_used),
        })
    head = {"frames": frames_used, "window": window, "max_n": MAX_N, "min_fraction": MIN_FRACTION, "step_tolerance": STEP_TOL, "separation": SEPARATION,
            "candidates": ",".join(mode_name("T", f).replace("T", "") for f in families), "source": "GS vectors" if first["g"] is not None else "covariant vectors (the frames carry no GS vectors)",
            "resolved_alike": alike,
            "other_steps": ";".join(f"{st[0] + 1}..{st[0] + st[1]}:{n}" for st, n in sorted(found.items()) if st not in {x for x, _ in steps})}
    out = {"modes.csv": rows, "modes.json": head, "modes_fits.csv": [], "modes_lp.csv": [], "patterns": {}, "pattern_captions": []}
    # modes_fits.csv, scope "mean": the two-fold steps classified T of one wave vector.
    for (st, _), c, a in zip(steps, chosen, (acc[st] for st, _ in steps)):
        if c is None or KINDS[c % 4] != "T" or len(families[c // 4][0]) != 1 or st[1] != 2:
            continue
        w = families[c // 4][0][0]
        mean = np.mean(np.array(a["fits"], float), axis=0)  # (source x vector, family, 6)
        for si, src in enumerate(("GS", "CLV")):
            for j in range(2):
                v = mean[si * 2 + j, c // 4]
                if not np.all(np.isnan(v)):
                    out["modes_fits.csv"].append(dict(zip(FIT_KEYS, [str(st[0] + 1), str(st[0] + 2), str(st[0] + j + 1), src, str(w[0]), str(w[1]), "mean"])) | dict(zip(FIT_COLS, v)))
    # The pattern tables at the shown frame: positive steps classified as a mode with its
    # degeneracy, each of its wave vectors; T: Fig. 10 (last vector of a pair of one wave
    # vector; in a step of several, the group's least-squares match of the wave's cos
    # pattern of dq, with dq along k as a check), else Figs. 11, 12.
    phase, g, v = first["phase"], first["g"], first["v"]

    def reconstructed(group, part, t):
        """The group's combination whose `part` best matches pattern t: (unit vector signed
        to overlap t positively, |cos| of its part and t)."""
        coef, *_ = np.linalg.lstsq(group[part], t, rcond=None)
        vec = group @ coef
        dot = vec[part] @ t
        overlap = abs(dot) / (np.linalg.norm(vec[part]) * np.linalg.norm(t))
        return vec * np.sign(dot) / np.linalg.norm(vec), overlap

    for (st, _), c in zip(steps, chosen):
        if c is None or not st[0] + st[1] <= d // 2 - 3 or not matches_degeneracy(st[1], c, families):
            continue
        waves = families[c // 4][0]
        several = len(waves) > 1
        groups = ([("GS", g[:, st[0] : st[0] + st[1]])] if g is not None else []) + [("CLV", v[:, st[0] : st[0] + st[1]])]
        for w in waves:
            k = wave_norm(w, lx, ly)
            along, across = (np.array(x) for x in wave_axes(w, lx, ly))
            span, xname, a_name, t_name = pattern_axes(w, lx, ly)
            x = np.mod(phase[: 2 * n].reshape(n, 2) @ along, span)
            # file stems: "T1" for (1,0), "T1_m1" for (1,-1); the LP figures' "LP" whether L, P or LP
            stem = lambda kind: f"{kind}{w[0]}" if w[1] == 0 else f"{kind}{w[0]}_{w[1]}".replace("-", "m")  # noqa: E731
            if KINDS[c % 4] == "T":
                i = st[0] + st[1] - 1
                if several:
                    cos = mode_patterns("T", ([w], k), phase, lx, ly)[:, 0]
                    sources = [(src, reconstructed(group, slice(0, 2 * n), cos)[0]) for src, group in groups]
                else:
                    sources = ([("GS", g[:, i])] if g is not None else []) + [("CLV", v[:, i] * (-1.0 if g is not None and g[:, i] @ v[:, i] < 0 else 1.0))]
                cols = {xname: x}
                for part, comp in ((slice(0, 2 * n), f"dq{t_name}"), (slice(2 * n, 4 * n), f"dp{t_name}")):
                    for src, vec in sources:
                        cols[f"{comp}_{src.lower()}"] = vec[part].reshape(n, 2) @ across
                    if several and comp.startswith("dq"):
                        for src, vec in sources:
                            cols[f"dq{a_name}_{src.lower()}"] = vec[part].reshape(n, 2) @ along
                out["patterns"][f"fig10_{stem('T')}_i{i + 1}.csv"] = cols
                name, family = mode_name("T", ([w], k)), mode_name("T", families[c // 4])
                out["pattern_captions"].append({"title": f"Transverse mode {name} of {family} (Fig. 10)" if several else f"Transverse mode {name} (Fig. 10)", "kind": "T", "name": name, "several": several, "i": i + 1, "first": st[0] + 1, "last": st[0] + st[1], "step": first["step"], "k": k, "overlaps": [(src, reconstructed(group, slice(0, 2 * n), cos)[1]) for src, group in groups] if several else []})
                if not several:
                    for src, vec in sources:
                        out["modes_fits.csv"].append(dict(zip(FIT_KEYS, [str(st[0] + 1), str(st[0] + st[1]), str(i + 1), src, str(w[0]), str(w[1]), f"step {first['step']}"])) | dict(zip(FIT_COLS, fit_values(*across_fits(vec, phase, w, lx, ly)))))
            else:
                targets = mode_patterns("LP", ([w], k), phase, lx, ly)  # L cos, L sin, P cos, P sin
                cols = {xname: x}
                for fig, part, ch, pattern in ((11, slice(0, 2 * n), "q", "sin"), (12, slice(2 * n, 4 * n), "p", "cos")):
                    for src, group in groups:
                        for which, t in (("L", targets[:, 1 if pattern == "sin" else 0]), ("P", targets[:, 3 if pattern == "sin" else 2])):
                            vec, overlap = reconstructed(group, part, t)
                            field = vec[part].reshape(n, 2)
                            if which == "L":
                                y = field @ along
                                cols[f"fig{fig}_L_d{ch}{a_name}_{src.lower()}"] = y
                                cols[f"fig{fig}_L_d{ch}{t_name}_{src.lower()}"] = field @ across
                            else:
                                pn = phase[2 * n :].reshape(n, 2)
                                y = (field * pn).sum(axis=1) / (pn**2).sum(axis=1)
                                cols[f"fig{fig}_P_d{ch}_over_p_{src.lower()}"] = y
                            amp, ph, res = fit_sine(x, y, k)
                            out["modes_lp.csv"].append({"first": str(st[0] + 1), "last": str(st[0] + st[1]), "n_x": str(w[0]), "n_y": str(w[1]), "source": src, "figure": str(fig), "pattern": f"{which}_{pattern}", "overlap": overlap, "amplitude": amp, "phase": ph, "residual": res})
                out["patterns"][f"{stem('LP')}_i{st[0] + 1}.csv"] = cols
                name, family = mode_name("LP", ([w], k)), mode_name("LP", families[c // 4])
                rms = lambda y: math.sqrt(np.mean(np.asarray(y) ** 2))  # noqa: E731
                srcs = [src for src, _ in groups]
                off = []
                for fig in (11, 12):
                    for which in ("L", "P"):
                        ys = [y for col, y in cols.items() if col.startswith(f"fig{fig}_{which}_")]
                        r = robust_range(np.concatenate(ys))
                        if r is not None:
                            off.append((fig, which) + r)
                out["pattern_captions"].append({"title": f"Longitudinal-momentum mode {name} (Figs. 11, 12)" if not several else f"Longitudinal-momentum mode {name} of {family} (Figs. 11, 12)", "kind": "LP", "name": name, "family": f"the {family} step", "several": several, "first": st[0] + 1, "last": st[0] + st[1], "step": first["step"], "rms": [(src, rms(cols[f"fig11_L_dq{t_name}_{src.lower()}"]) / rms(cols[f"fig11_L_dq{a_name}_{src.lower()}"])) for src in srcs], "off": off})
    # modes_dispersion.csv: the positive, consistently classified steps by kind, then |k|.
    titles = {}
    for pc in out["pattern_captions"]:
        pc["title"] = numbered(titles, pc["title"])
        titles[pc["title"]] = True
    disp = [r for r in rows if r["side"] == "+" and r["consistent"] == "true" and np.isfinite(r["k"]) and np.isfinite(r["lambda"])]
    disp.sort(key=lambda r: (r["kind"], r["k"]))
    out["modes_dispersion.csv"] = [{"kind": r["kind"], "name": r["name"], "n_x": r["n_x"], "n_y": r["n_y"], "k": r["k"], "lambda": r["lambda"], "stderr": s[int(r["first"]) - 1 : int(r["last"])].sum() / int(r["degeneracy"]), "spread": r["spread"], "lambda_over_k": r["lambda"] / r["k"]} for r in disp]
    return out, steps


def robust_range(values):
    """The y range of a pattern figure: 5th and 95th percentiles (of the finite values, at
    least 20), widened by their distance on either side; (lo, hi, points beyond, finite
    points) where a point lies beyond it, else None."""
    v = sorted(x for x in values if math.isfinite(x))
    if len(v) < 20:
        return None
    p5, p95 = v[len(v) // 20], v[len(v) - 1 - len(v) // 20]
    lo, hi = p5 - (p95 - p5), p95 + (p95 - p5)
    off = sum(1 for x in v if x < lo or x > hi)
    return (lo, hi, off, len(v)) if off else None


FIT_KEYS = ("first", "last", "i", "source", "n_x", "n_y", "scope")
FIT_COLS = ("amp_dqt", "resid_dqt", "rel_resid_dqt", "amp_dpt", "resid_dpt", "rel_resid_dpt")


# ---------------------------------------------------------------------------------------
# Figs. 16-17: Theta = arccos |v^i . v^j| over the pairs of F^(J).

THETA_BINS = 90  # on [0, pi/2], one degree wide
# An angle within this of a bin edge may fall on either side of it in clv, which takes
# arccos of the normalised dot product (error ~1e-16 / sin Theta <= 1e-13 above 1e-3 rad,
# below which it switches to the same 2 arcsin(|v^i -+ v^j| / 2) as here): such an angle
# counts in either bin.
THETA_EDGE = 1e-10
PAPER_SEPARATIONS = (1, 2, 4, 20, 50, 100, 200, 300)


def f_size(d, steps):
    """J of F^(J): the paper's 370 of 2N - 3 = 393 positive exponents scaled to this
    system's m = 2N - 3 (rounded half up), at most m, ending before the first positive mode step."""
    m = d // 2 - 3
    before = min((st[0] for st in steps if st[0] + st[1] <= m), default=m)
    return min(math.floor(370 * m / 393 + 0.5), m, before)


def theta_separations(d, j):
    """Fig. 16's separations: 1, 2, 4, the paper's larger ones scaled by D/792 (at least 1),
    each once, all below J."""
    return sorted(x for x in {s if s <= 4 else max(math.floor(s * d / 792 + 0.5), 1) for s in PAPER_SEPARATIONS} if x < j)


def thetas(v, s, j):
    """Theta of the pairs (v^a, v^(a+s)), a + s <= J, of every frame of v (T, D, k): (T, J - s)."""
    f = v[:, :, :j]
    a, b = f[:, :, s:], f[:, :, :-s]
    sign = np.where(np.einsum("tdk,tdk->tk", a, b) >= 0, 1.0, -1.0)
    return 2 * np.arcsin(np.minimum(np.linalg.norm(a - sign[:, None, :] * b, axis=1) / 2, 1.0))


def theta_histogram(theta):
    """Counts of THETA_BINS bins on [0, pi/2] (the last one closed) of the angles that are
    clearly inside one bin, the number of finite angles, and per bin how many angles within
    THETA_EDGE of one of its edges might be counted in it."""
    theta = theta[np.isfinite(theta)].ravel()
    w = math.pi / 2 / THETA_BINS
    edge = np.rint(theta / w)
    near = (np.abs(theta - edge * w) < THETA_EDGE) & (edge >= 1) & (edge < THETA_BINS)
    counts = np.bincount(np.minimum((theta[~near] / w).astype(int), THETA_BINS - 1), minlength=THETA_BINS)
    maybe = np.bincount(edge[near].astype(int) - 1, minlength=THETA_BINS) + np.bincount(edge[near].astype(int), minlength=THETA_BINS + 1)[:THETA_BINS]
    return counts, theta.size, maybe


# ---------------------------------------------------------------------------------------
# Convergence of the spectra: the running estimates and the drift and independence tests
# of the batch means (convergence_gs.csv, convergence_clv.csv, convergence_tests.csv).


def block_means(x, blocks):
    """The batch means of batch_stderr, oldest block first: (n, k) and the block length L."""
    t = x.shape[0]
    length = max(t // blocks, 1)
    count = t // length
    return x[t - count * length :].reshape(count, length, -1).mean(axis=1), length


def student_t_two_sided(t, dof):
    """P(|T| > t) for Student's t with an integer number of degrees of freedom, by the finite
    series of Abramowitz & Stegun 26.7.3-4 (exact but for round-off, ~1e-16 absolute)."""
    dof = int(round(dof))
    theta = math.atan(abs(t) / math.sqrt(dof))
    s, c = math.sin(theta), math.cos(theta)
    if dof % 2 == 0:
        term, total = 1.0, 1.0
        for j in range(1, dof // 2):
            term *= (2 * j - 1) / (2 * j) * c * c
            total += term
        a = s * total
    else:
        total = 0.0
        if dof > 1:
            term, total = c, c
            for j in range(1, (dof - 1) // 2):
                term *= (2 * j) / (2 * j + 1) * c * c
                total += term
        a = 2 / math.pi * (theta + s * total)
    return 1.0 - a


def halves_z(x):
    """(mean of the newer half - mean of the older half) / the standard error of that
    difference (the middle one of an odd count left out)."""
    h = len(x) // 2
    old, new = x[:h], x[len(x) - h :]
    se = lambda y: np.std(y, ddof=1) / math.sqrt(len(y))  # noqa: E731
    return (new.mean() - old.mean()) / math.hypot(se(old), se(new))


def diagnose(means, neutral):
    """The drift and independence tests of block means (n, k), oldest first, over the
    exponents outside `neutral` whose spread over the blocks exceeds 1e-9 of the largest:
    the fraction with |z| > 2, the largest |z| and its index, z of the sum of those whose
    mean is positive and its two-sided Student t chance (2 (n//2 - 1) degrees of freedom),
    the mean lag-1 autocorrelation r_1 and its limit -1/n + 2/sqrt(n); None with fewer than
    4 blocks or none that vary."""
    nb, k = means.shape
    if nb < 4:
        return None
    spread = means.std(axis=0, ddof=1)
    scale = np.nanmax(spread, initial=0.0)
    varies = [i for i in range(k) if scale > 0 and spread[i] > 1e-9 * scale and i not in neutral]
    if not varies:
        return None
    z = np.array([halves_z(means[:, i]) for i in varies])
    dev = means[:, varies] - means[:, varies].mean(axis=0)
    r1 = ((dev[1:] * dev[:-1]).sum(axis=0) / (dev**2).sum(axis=0)).mean()
    top = int(np.argmax(np.abs(z))) if np.abs(z).max() > 0 else None
    positive = [i for i in varies if means[:, i].sum() > 0]
    sum_z = halves_z(means[:, positive].sum(axis=1)) if positive else math.nan
    dof = 2 * (nb // 2 - 1)
    return {
        "blocks": nb, "tested": len(varies), "drifting_fraction": np.mean(np.abs(z) > 2), "max_abs_z": 0.0 if top is None else abs(z[top]),
        "max_z_index": 1 if top is None else varies[top] + 1, "h_ks_z": sum_z,
        "h_ks_chance": student_t_two_sided(sum_z, dof) if math.isfinite(sum_z) else 1.0, "r1": r1, "r1_limit": -1 / nb + 2 / math.sqrt(nb),
    }


def final_block_length(planned, steps, blocks):
    """The block length at the end of a forward run of `steps` measured steps whose blocks
    were planned `planned` steps long, with clv's doubling rule: after each measured step, a
    block closes when the count of steps is a multiple of the length; once 2 `blocks` or
    more are closed, an even number of them, with no step in an unfinished block, neighbours
    merge pairwise and the length doubles."""
    length, closed = max(int(planned), 1), 0
    for s in range(1, steps + 1):
        if s % length == 0:
            closed += 1
            if closed >= 2 * max(blocks, 1) and closed % 2 == 0:
                closed //= 2
                length *= 2
    return length


def forward_from_r(run_dir):
    """The forward GS spectrum of a run directory recomputed from its stored R_n (see --run in
    the docstring): exponents, stderr, block means (oldest first), the block lengths, the
    steps used. Stops (sys.exit) if a measured step's R_n is not stored."""
    with open(os.path.join(run_dir, "run.json")) as f:
        run = json.load(f)
    config = run.get("config", run)
    relax, steps, tau, blocks = int(config["relax_steps"]), int(config["steps"]), float(config["tau"]), int(config["blocks"])
    first, last = relax + 1, relax + steps  # n of the measured R_n
    diag, planned = {}, None
    paths = sorted(glob.glob(os.path.join(run_dir, "seg-*-*.mcap")))
    if not paths:
        sys.exit(f"{run_dir}: no segment files (seg-*-*.mcap): not a run directory")
    for path in paths:
        for topic, n, m in read_segment(path):
            if topic == "r" and first <= n <= last:
                k = int(m["k"])
                j = np.arange(k)
                d = np.array(m["r"][j * (j + 1) // 2 + j])  # R_jj in the packed upper triangle
                if n in diag and diag[n].tobytes() != d.tobytes():
                    sys.exit(f"{run_dir}: R_{n} is stored twice with different diagonals")
                diag[n] = d
            elif topic == "checkpoint" and int(m["acc_steps"]) == 0 and n <= relax:
                if planned is None or n < planned[0]:
                    planned = (n, int(m["acc_block_len"]))
    missing = [n for n in range(first, last + 1) if n not in diag]
    if missing:
        store = run.get("store", {})
        sys.exit(
            f"{run_dir}: R_n of {len(missing)} of the {steps} measured steps n = {first}..{last} are not stored "
            f"(the first missing: {missing[:5]}); the run keeps R_n at its checkpoints and, with --store-r all, at the steps "
            f"after the window start relax_steps + steps - clv_steps - transient (here store_r = {store.get('store_r')}, "
            f"clv_steps = {store.get('clv_steps')}, transient = {store.get('transient')}): lambda_gs is recomputable only from "
            f"a run made with --store-r all and --clv-steps + --transient = --steps"
        )
    logs = np.log(np.array([diag[n] for n in range(first, last + 1)]))  # (steps, k), oldest first
    plan = planned[1] if planned is not None else max(steps // max(blocks, 1), 1)
    length = final_block_length(plan, steps, blocks)
    count = steps // length
    means = logs[: count * length].reshape((count, length, logs.shape[1])).sum(axis=1) / (length * tau)
    stderr = means.std(axis=0, ddof=1) / np.sqrt(count) if count >= 2 else np.full(logs.shape[1], np.nan)
    return {
        "exponents": logs.sum(axis=0) / (steps * tau),
        "stderr": stderr,
        "block_means": means,
        "block_steps": length,
        "planned_block_steps": plan,
        "plan_from": "checkpoint" if planned is not None else "run.json",
        "steps": [first, last],
        "config": config,
    }


def compare_spectrum_json(c, table, mine, spectrum):
    """mine (forward_from_r) against a spectrum.json: exponents, stderr, the block length and
    the block means."""
    k = len(mine["exponents"])
    i = np.arange(1, k + 1)
    theirs = lambda x: np.array([np.nan if y is None else y for y in x], float)  # noqa: E731
    c.compare(table, "exponents", i, mine["exponents"], theirs(spectrum.get("exponents", [np.nan] * k)))
    c.compare(table, "stderr", i, mine["stderr"], theirs(spectrum.get("stderr", [np.nan] * k)), TOL_ERR)
    b = spectrum.get("blocks") or {}
    c.compare(table, "blocks.block_steps", np.array([1]), [mine["block_steps"]], [float(b.get("block_steps", np.nan))])
    rows = b.get("exponents") or []
    if len(rows) != len(mine["block_means"]):
        c.bad.append(f"disagreement: {table} blocks.exponents has {len(rows)} blocks, mine {len(mine['block_means'])}")
        return
    for n, (x, y) in enumerate(zip(mine["block_means"], rows)):
        c.compare(table, f"blocks.exponents[{n}]", i, x, theirs(y))


# ---------------------------------------------------------------------------------------
# Captions: the numbers index.html states, against the recomputation above (or, for
# round-off, against the report's own table that was checked above).

NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:e[-+]?\d+)?|NaN|nan|inf|-inf"


def caption_sections(path):
    """{title: caption} of index.html: each <section>'s <h2> and the text of its <p> after the
    figures (not its "Numbers:" line), HTML entities undone, tags (none so far) dropped."""
    if not os.path.exists(path):
        return None
    with open(path, encoding="utf-8") as f:
        page = f.read()
    out = {}
    for title, body in re.findall(r"<section><h2>(.*?)</h2>(.*?)</section>", page, re.S):
        paragraphs = [html.unescape(re.sub(r"<[^>]*>", "", p)) for p in re.findall(r"<p>(.*?)</p>", body, re.S)]
        out[numbered(out, html.unescape(title))] = " ".join(p for p in paragraphs if not p.startswith("Numbers:"))
    return out


def numbered(seen, title):
    """`title`, or "title #2", "#3", ... where `seen` has it already (two steps of one mode
    give two sections of one title)."""
    k = 1
    while (title if k == 1 else f"{title} #{k}") in seen:
        k += 1
    return title if k == 1 else f"{title} #{k}"


def half_unit(printed):
    """Half a unit of the last digit a number is printed with: "3.0903e-2" -> 5e-7, "75.7" -> 0.05."""
    mantissa, _, exp = printed.lower().lstrip("+-").partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 0.5 * 10.0 ** (int(exp or 0) - decimals)


class Captions:
    """The captions of a report, checked phrase by phrase against the checker's numbers."""

    def __init__(self, checker, sections):
        self.c, self.sections, self.checked = checker, sections, {}

    def has(self, title):
        return title in self.sections

    def find(self, title, pattern, what, every=False):
        """The match of the regular expression `pattern` in the caption of `title` (all of
        them with every=True); a caption without it is a disagreement (None, or [])."""
        text = self.sections.get(title, "")
        found = list(re.finditer(pattern, text)) if every else re.search(pattern, text)
        if not found:
            said = re.sub(r"\\(.)", r"\1", pattern.replace(NUMBER, "X"))
            self.c.bad.append(f"disagreement: caption '{title}' {what}: no phrase like '{said[:120]}'")
        self.checked.setdefault(title, [])
        return found

    def number(self, title, what, mine, printed, rel=1e-9, half=None):
        """A number as the caption prints it agrees with mine rounded to that precision:
        |mine - printed| <= half a unit of its last digit (or `half`, for a number printed
        with its trailing zeros trimmed), + rel |mine| for the round-off of two computations
        of the same value (a number on a rounding edge may go either way)."""
        self.checked.setdefault(title, []).append(what)
        mine = float(mine)
        if printed.lower().lstrip("+-") in ("nan", "inf"):
            ok = printed.lower() == repr(mine).lower() or (math.isnan(mine) and printed.lower() == "nan")
        else:
            ok = math.isfinite(mine) and abs(mine - float(printed)) <= (half or half_unit(printed)) * (1 + 1e-9) + rel * abs(mine)
        if not ok:
            self.c.bad.append(f"disagreement: caption '{title}' {what} mine {mine!r} caption {printed}")

    def numbers(self, title, what, mine, printed_list, rel=1e-9):
        """The numbers of a list ("a, b, c" split by the caller) against mine, one by one;
        a list of another length is a disagreement."""
        if len(mine) != len(printed_list):
            self.c.bad.append(f"disagreement: caption '{title}' {what}: {len(printed_list)} numbers, mine {len(mine)}")
            return
        for k, (m, p) in enumerate(zip(mine, printed_list)):
            self.number(title, f"{what} [{k + 1}]", m, p, rel)

    def text(self, title, what, mine, printed):
        """A word or an index as printed must be mine exactly."""
        self.checked.setdefault(title, []).append(what)
        if str(mine) != str(printed):
            self.c.bad.append(f"disagreement: caption '{title}' {what} mine {mine} caption {printed}")


def split_numbers(s):
    return re.findall(NUMBER, s)


def h_ks(x, neutral, blocks):
    """h_KS = the sum of the positive exponents outside `neutral` (0-based) of the time means
    of x (rows: frames, increasing step), and its batch-means error: that of the per-frame sum
    of the same exponents (clv: the per-block sums of those whose mean is positive)."""
    mean = x.mean(axis=0)
    keep = [i for i in range(x.shape[1]) if mean[i] > 0 and i not in neutral]
    return mean[keep].sum() + 0.0, batch_stderr(x[:, keep].sum(axis=1)[:, None], blocks)[0]


def check_captions(c, caps, f):
    """Check the numbers of the captions against `f`, the facts recomputed in main()."""
    n, d, k, blocks, frames = f["n"], f["d"], f["k"], f["blocks"], f["frames"]
    local, gs_local, forward, config = f["local"], f["gs_local"], f["forward"], f["config"]
    neutral = range(max(2 * n - 3, 0), 2 * n + 3)
    disks_full = k == d and n >= 2

    # Fig. 2: h_KS of the window's GS and CLV spectra and of the whole run, the shear model of
    # the last three null-space exponents, the sum of the whole run's GS exponents.
    t = "Lyapunov spectrum (Fig. 2)"
    if caps.has(t):
        same = gs_local is not None
        m = caps.find(t, rf"Kolmogorov-Sinai entropy h_KS, the sum of the positive exponents \(Pesin's identity\): ({NUMBER})(?: ± ({NUMBER}))? \(GS\), ({NUMBER})(?: ± ({NUMBER}))? \(CLV\)", "h_KS")
        if m:
            clv_h, clv_e = h_ks(local, neutral, blocks)
            caps.number(t, "h_KS (CLV)", clv_h, m.group(3))
            if m.group(4) or math.isfinite(clv_e):
                caps.number(t, "h_KS error (CLV)", clv_e, m.group(4) or "nan")
            if same:
                gs_h, gs_e = h_ks(gs_local, neutral, blocks)
                caps.number(t, "h_KS (GS, frames' steps)", gs_h, m.group(1))
                if m.group(2) or math.isfinite(gs_e):
                    caps.number(t, "h_KS error (GS, frames' steps)", gs_e, m.group(2) or "nan")
        run = f["forward_exponents"]
        run_h = None
        if run is not None:
            run_h = sum(x for i, x in enumerate(run) if x > 0 and i not in neutral) + 0.0
        if same and run is not None:
            m = caps.find(t, rf"The GS spectrum over the whole forward run \((\d+) steps\) is more precise .*?: h_KS = ({NUMBER})(?: ± ({NUMBER}))?\.", "h_KS (whole run)")
            if m:
                caps.text(t, "whole run's steps", config.get("steps"), m.group(1))
                caps.number(t, "h_KS (GS, whole run)", run_h, m.group(2))
                if m.group(3):
                    caps.number(t, "h_KS error (GS, whole run)", f["forward_h_ks_stderr"], m.group(3))
        elif run is not None and m:  # frames without GS exponents: "(GS)" is the whole run's
            caps.number(t, "h_KS (GS, whole run)", run_h, m.group(1))
            if m.group(2):
                caps.number(t, "h_KS error (GS, whole run)", f["forward_h_ks_stderr"], m.group(2))
        if f["shear"] is not None and k >= 2 * n + 3:
            s1, s2, mean, consecutive = f["shear"]
            if consecutive:
                m = caps.find(t, rf"so over s = ({NUMBER})\.\.({NUMBER}) they average -ln\(\(1 \+ s2²\)/\(1 \+ s1²\)\) / \(2 \(s2 - s1\)\) = ({NUMBER}); measured ((?:{NUMBER})(?:, (?:{NUMBER}))*)\.", "null-shear prediction")
            else:
                m = caps.find(t, rf"so over the (\d+) frames' steps, within s = ({NUMBER})\.\.({NUMBER}), the mean of each step's -ln\(\(1 \+ s²\)/\(1 \+ \(s - τ\)²\)\) / \(2τ\) is ({NUMBER}); measured ((?:{NUMBER})(?:, (?:{NUMBER}))*)\.", "null-shear prediction")
                if m:
                    caps.text(t, "null-shear frames", frames, m.group(1))
            if m:  # the last four groups of either phrase: s1, s2, the prediction, the measured
                g = m.groups()[-4:]
                caps.number(t, "null-shear s1", s1, g[0])
                caps.number(t, "null-shear s2", s2, g[1])
                caps.number(t, "null-shear prediction", mean, g[2])
                caps.numbers(t, "null-shear measured lambda_2N+1..2N+3", local.mean(axis=0)[2 * n : 2 * n + 3], split_numbers(g[3]))
        if forward is not None and k == d and len(forward["exponents"]) == d:
            m = caps.find(t, rf"Sum of the whole run's GS exponents: ({NUMBER}), exactly 0 \(phase-space volume is kept\)\.", "sum of the GS exponents")
            if m:  # round-off (~1e-13 of exponents ~5) printed with 3 digits: only the same
                # doubles (spectrum.json's, which spectrum.csv's lambda_gs copies) summed in
                # the same order (i = 1..D, one at a time, as clv does) give its digits
                caps.number(t, "sum of the whole run's GS exponents", sum(float(x) for x in forward["exponents"]), m.group(1), rel=0.0)

    # Fig. 8: the plotted range and the median errors of the plotted exponents.
    t = "Mode region of the spectrum (Fig. 8)"
    if caps.has(t) and disks_full:
        last = 2 * n - 4
        first = max(last - max(d // 6, 8), 0)
        m = caps.find(t, r"The positive exponents λ_(\d+)\.\.λ_(\d+) next to the null space", "plotted range")
        if m:
            caps.text(t, "first plotted index", first + 1, m.group(1))
            caps.text(t, "last plotted index", last + 1, m.group(2))
        shown = [i for j in range(first, last + 1) for i in (j, d - 1 - j)]
        clv_err = batch_stderr(local, blocks)
        gs_err = batch_stderr(gs_local, blocks) if gs_local is not None else f["forward_stderr"]
        med = lambda e: np.median([x for x in np.asarray(e, float)[shown] if np.isfinite(x)]) if e is not None and np.isfinite(np.asarray(e, float)[shown]).any() else np.nan  # noqa: E731
        if math.isfinite(med(gs_err)):
            m = caps.find(t, rf"Median standard errors of the plotted exponents: ({NUMBER}) \(GS\), ({NUMBER}) \(CLV\)", "median errors")
            if m:
                caps.number(t, "median stderr (GS)", med(gs_err), m.group(1))
                caps.number(t, "median stderr (CLV)", med(clv_err), m.group(2))
        elif math.isfinite(med(clv_err)):
            m = caps.find(t, rf"Median standard error of the plotted CLV exponents: ({NUMBER})", "median error")
            if m:
                caps.number(t, "median stderr (CLV)", med(clv_err), m.group(1))

    # Convergence: each spectrum's test numbers (those of convergence_tests.csv).
    t = "Convergence of the spectra (beyond the paper)"
    if caps.has(t):
        for test in f["tests"]:
            label = "GS" if test["spectrum_0gs_1clv"] == "0" else "CLV"
            m = caps.find(t, rf"{label}: (\d+) blocks of (\d+) steps; ({NUMBER}) % of (\d+) exponents have \|z\| > 2 \(by chance ({NUMBER}) %; largest \|z\| = ({NUMBER}), i = (\d+)\); (?:h_KS|sum of the k \(all positive\) exponents): z = ({NUMBER}) \(as large by chance: ({NUMBER}) %\); r_1 = ({NUMBER}) \(limit ({NUMBER})\)", f"{label} tests")
            if not m:
                continue
            nb = test["blocks"]
            caps.text(t, f"{label} blocks", nb, m.group(1))
            caps.text(t, f"{label} block steps", int(test["block_steps"]), m.group(2))
            caps.number(t, f"{label} drifting %", 100 * test["drifting_fraction"], m.group(3))
            caps.text(t, f"{label} tested", test["tested"], m.group(4))
            caps.number(t, f"{label} chance %", 100 * student_t_two_sided(2.0, 2 * (nb // 2 - 1)), m.group(5))
            caps.number(t, f"{label} largest |z|", test["max_abs_z"], m.group(6))
            caps.text(t, f"{label} largest |z| index", test["max_z_index"], m.group(7))
            caps.number(t, f"{label} z of h_KS", test["h_ks_z"], m.group(8))
            caps.number(t, f"{label} h_KS chance %", 100 * test["h_ks_chance"], m.group(9))
            caps.number(t, f"{label} r_1", test["r1"], m.group(10))
            caps.number(t, f"{label} r_1 limit", test["r1_limit"], m.group(11))

    # Fig. 5: the frames and the blocks of the errors.
    t = "Localization (Fig. 5)"
    sampled = f["sampled"]
    if caps.has(t):
        m = caps.find(t, r"averaged over (\d+) frames for (?:GS and )?covariant vectors", "frames")
        if m:
            caps.text(t, "frames", len(sampled), m.group(1))
        b = max(len(sampled) // blocks, 1)
        caps.find(t, rf"standard errors from blocks of {b} frames" if len(sampled) >= 2 * b else rf"they need at least two blocks of {b} frames", f"blocks of {b} frames")

    v, g = f["v"], f["g"]
    shear = range(2 * n, 2 * n + 3)
    # Fig. 3: <|g^i . v^i|> at i = 2N+1..2N+3.
    t = "Gram-Schmidt versus covariant vectors (Fig. 3)"
    if caps.has(t) and g is not None and k >= 2 * n + 3:
        m = caps.find(t, rf"It is 1 at i = 1 and i = 2N-2 = (\d+), .*? At i = (\d+)\.\.(\d+) \(black open rings: not converged\) it is ([^:]*\d):", "<|g.v|> of the sheared null vectors")
        if m:
            caps.text(t, "2N-2", 2 * n - 2, m.group(1))
            caps.text(t, "2N+1..2N+3", f"{2 * n + 1}..{2 * n + 3}", f"{m.group(2)}..{m.group(3)}")
            mean = np.abs(np.einsum("tdi,tdi->ti", g, v)).mean(axis=0)
            caps.numbers(t, "<|g.v|> at 2N+1..2N+3", mean[list(shear)], split_numbers(m.group(4)))

    # Figs. 6, 7: the conjugate symmetry of eta_q, eta_p and eta_q of the sheared null CLVs.
    for t, x, sym in (("Position and momentum content of the GS vectors (Fig. 6)", g, "η_p"), ("Position and momentum content of the covariant vectors (Fig. 7)", v, "η_q")):
        if not caps.has(t) or x is None:
            continue
        means, _ = projections(x, n)
        q, other = means["eta_q"], means["eta_p" if sym == "η_p" else "eta_q"]
        if k == d:
            m = caps.find(t, rf"Conjugate symmetry: max_i \|η_q\(i\) - {sym}\(4N\+1-i\)\| = ({NUMBER})", "conjugate symmetry")
            if m:
                caps.number(t, "conjugate asymmetry", np.max(np.abs(q - other[::-1])), m.group(1))
        if sym == "η_q" and k >= 2 * n + 3:
            m = caps.find(t, rf"and the last three, i = {2 * n + 1}\.\.{2 * n + 3} \(η_q = ([^)]*)\)", "eta_q of the sheared null vectors")
            if m:
                caps.numbers(t, "eta_q at 2N+1..2N+3", q[list(shear)], split_numbers(m.group(1)))

    # Tables I, II: the first row of beta and alpha, the frame, the largest angles over time
    # and alpha's corner. Round-off (e_4..e_6 entries, the angles, the corner) is not
    # recomputable digit for digit: against the report's own tables, checked above.
    t = "Null space (Tables I, II)"
    if caps.has(t) and k >= 2 * n + 3:
        at = sampled[0]
        m = caps.find(t, r"onto e_1\.\.e_6 at the earliest consumed frame \(step (\d+), t = ([^;]*); ", "frame")
        if m:
            caps.text(t, "step", at["step"], m.group(1))
            caps.number(t, "time", at["time"], m.group(2), half=5e-7)  # {:.6} with its trailing zeros trimmed
        m = caps.find(t, r"Row i = (\d+): β = \[([^\]]*)\](?:, α = \[([^\]]*)\])?\.", "first row")
        for name, table, group in (("beta", "nullspace_beta.csv", 2), ("alpha", "nullspace_alpha.csv", 3)):
            rows = read_csv(os.path.join(f["report"], table))
            if not m or rows is None or not len(rows.get("i", [])):
                continue
            caps.text(t, "row", int(rows["i"][0]), m.group(1))
            if m.group(group) is None:
                caps.c.bad.append(f"disagreement: caption '{t}' first row of {name}: not there")
                continue
            caps.numbers(t, f"{name} row {int(rows['i'][0])}", [rows[f"e{q + 1}"][0] for q in range(6)], split_numbers(m.group(group)))
        ns = read_csv(os.path.join(f["report"], "nullspace_series.csv"))
        if ns is not None and len(ns.get("step", [])):
            m = caps.find(t, rf"Maxima over time: CLV angle ({NUMBER})(?:, GS angle ({NUMBER}), GS-CLV angle ({NUMBER}))?", "largest angles")
            if m:
                for col, group in (("angle_clv", 1), ("angle_gs", 2), ("angle_gs_clv", 3)):
                    if m.group(group) is not None:
                        caps.number(t, f"largest {col}", np.nanmax(ns[col]), m.group(group))
        alpha = read_csv(os.path.join(f["report"], "nullspace_alpha.csv"))
        if alpha is not None and len(alpha.get("i", [])) >= 3:
            m = caps.find(t, rf"The entries α_\(i,4\.\.6\) of rows i = (\d+)\.\.(\d+), which the paper prints at about 1e-6, are at most ({NUMBER}) here", "alpha corner")
            if m:
                caps.number(t, "largest |alpha_(i,4..6)|", max(abs(alpha[f"e{q}"][r]) for r in range(3) for q in (4, 5, 6)), m.group(3))

    # Domination: the overall swap fraction at the first and the longest Delta, and the verdict
    # on E^u + E^0 + E^s.
    t = "Domination of the Oseledec splitting (Sec. 6)"
    deltas = f["deltas"]
    if caps.has(t) and deltas:
        m = caps.find(t, rf"Overall fraction at Δ = (\d+): ({NUMBER})(?:; at Δ = (\d+): ({NUMBER}) \(from (\d+) windows)?", "overall fractions")
        fits = [dl for dl in deltas if dl <= len(local)]
        if m:
            caps.text(t, "first Δ", deltas[0], m.group(1))
            caps.number(t, f"overall at Δ = {deltas[0]}", domination(window_sums(local, deltas[0]), n)["overall"], m.group(2))
            longest = max((w for w in range(len(deltas)) if deltas[w] <= len(local)), default=0)
            if longest > 0:
                dl = deltas[longest]
                x = window_sums(local, dl)
                if m.group(3) is None:
                    caps.c.bad.append(f"disagreement: caption '{t}' overall fraction at Δ = {dl}: not there")
                else:
                    caps.text(t, "longest Δ", dl, m.group(3))
                    caps.number(t, f"overall at Δ = {dl}", domination(x, n)["overall"], m.group(4))
                    caps.text(t, f"windows at Δ = {dl}", len(x), m.group(5))
        if k == d and d >= 8 and fits:
            splits = [[domination(window_sums(local, dl), n)[col] for col in ("split_unstable_null", "split_null_stable")] for dl in fits]
            quiet = [all(x == 0 for x in s) for s in splits]
            since = next((p for p in range(len(fits)) if all(quiet[p:])), None)
            pair = rf"({NUMBER}) and ({NUMBER})"
            if since == 0:
                caps.find(t, r"never violated, not even in single steps; it is dominated in these frames", "splitting verdict")
            elif since is not None:
                m = caps.find(t, rf"violated in {pair} of the windows at Δ = (\d+) and in none from Δ = (\d+) on", "splitting verdict")
                if m:
                    caps.numbers(t, f"split fractions at Δ = {fits[0]}", splits[0], [m.group(1), m.group(2)])
                    caps.text(t, "first Δ", fits[0], m.group(3))
                    caps.text(t, "Δ_0", fits[since], m.group(4))
            else:
                m = caps.find(t, rf"still violated at Δ = (\d+), in {pair} of the windows", "splitting verdict")
                if m:
                    caps.text(t, "longest Δ", fits[-1], m.group(1))
                    caps.numbers(t, f"split fractions at Δ = {fits[-1]}", splits[-1], [m.group(2), m.group(3)])

    # Table III: each step found, and how many frames resolve the same steps.
    t = "Lyapunov modes (Table III)"
    modes = f["modes"]
    if caps.has(t) and modes is not None and modes["modes.csv"]:
        lx, ly = f["lx"], f["ly"]
        m = caps.find(t, rf"with \|k\| ≤ 2π·{MAX_N}/max\(L_x, L_y\) = ({NUMBER})", "|k| bound")
        if m:
            caps.number(t, "largest |k|", 2 * math.pi * MAX_N / max(lx, ly), m.group(1))
        found = caps.find(t, rf"(\S+) at i = (\d+)\.\.(\d+) \((\d+)-fold(?:, (\w+))?, λ = ({NUMBER})(?: with its exponents spread over ({NUMBER}))?, fraction ({NUMBER})(?: of the best candidate (\S+), ({NUMBER}) beyond chance, below {MIN_FRACTION})?, ({NUMBER})% of frames agree, (\d+) of (\d+) find the step on their own\)", "steps found", every=True)
        rows = modes["modes.csv"]
        if found and len(found) != len(rows):
            caps.c.bad.append(f"disagreement: caption '{t}' steps found: {len(found)}, mine {len(rows)}")
        for r, m in zip(rows, found):
            at = f"i = {r['first']}..{r['last']}"
            caps.text(t, f"{at} step", f"{r['name']} at i = {r['first']}..{r['last']} ({r['degeneracy']}-fold", f"{m.group(1)} at i = {m.group(2)}..{m.group(3)} ({m.group(4)}-fold")
            caps.text(t, f"{at} detection", "" if r["detection"] == "degenerate" else r["detection"], m.group(5) or "")
            caps.number(t, f"{at} lambda", r["lambda"], m.group(6))
            if r["detection"] != "degenerate":
                caps.number(t, f"{at} spread", r["spread"], m.group(7) or "nan")
            caps.number(t, f"{at} fraction", r["fraction_gs"] if np.isfinite(r["fraction_gs"]) else r["fraction_clv"], m.group(8))
            if r["name"] != r["best"]:
                caps.text(t, f"{at} best candidate", r["best"], m.group(9))
                caps.number(t, f"{at} beyond chance", r["beyond_chance"], m.group(10) or "nan")
            caps.number(t, f"{at} agreement %", 100 * r["agreement"], m.group(11))
            caps.text(t, f"{at} frames resolving it", round(r["resolved"] * int(r["frames"])), m.group(12))
            caps.text(t, f"{at} frames", r["frames"], m.group(13))
        head = modes["modes.json"]
        m = caps.find(t, r"resolved at the first sampled frame read \(step (\d+), the newest: the backward stream delivers it first\); resolved at each frame on its own, (\d+) of (\d+) frames give the same steps \((no frame finds another step|other steps found by some frames: ([^;]*))", "resolution")
        if m:
            caps.text(t, "first frame's step", f["first_step"], m.group(1))
            caps.text(t, "frames resolving the same steps", head["resolved_alike"], m.group(2))
            caps.text(t, "frames", head["frames"], m.group(3))
            others = ";".join(f"{a}..{b}:{c_}" for a, b, c_ in re.findall(r"i = (\d+)\.\.(\d+) in (\d+)", m.group(5) or ""))
            caps.text(t, "other steps", head["other_steps"], others)

    # Figs. 10-12: the vector, step and frame shown, k, and for several wave vectors the
    # overlaps with the pattern; L's rms check ratio and the points drawn off scale.
    for pc in modes["pattern_captions"] if modes is not None else []:
        t = pc["title"]
        if not caps.has(t):
            caps.c.bad.append(f"disagreement: no caption '{t}'")
            continue
        span = rf"\(i = (\d+)\.\.(\d+)\)"
        if pc["kind"] == "T" and not pc["several"]:
            m = caps.find(t, rf"of vector i = (\d+) of the {re.escape(pc['name'])} pair {span} against s = .*? at step (\d+), .*?, k = ({NUMBER})\. ", "vector, step, k")
            if m:
                caps.text(t, "vector i", pc["i"], m.group(1))
                caps.text(t, "step", f"{pc['first']}..{pc['last']}", f"{m.group(2)}..{m.group(3)}")
                caps.text(t, "frame's step", pc["step"], m.group(4))
                caps.number(t, "k", pc["k"], m.group(5))
        elif pc["kind"] == "T":
            m = caps.find(t, rf"reconstructed at step (\d+) inside the (\d+)-dimensional .*? step {span} .*?, k = ({NUMBER})\. \|cos\| between the reconstructed δq and the pattern \(1 where the pattern lies in the span\): (.*?)\. δq", "step, k, overlaps")
            if m:
                caps.text(t, "frame's step", pc["step"], m.group(1))
                caps.text(t, "step", f"{pc['last'] - pc['first'] + 1}: {pc['first']}..{pc['last']}", f"{m.group(2)}: {m.group(3)}..{m.group(4)}")
                caps.number(t, "k", pc["k"], m.group(5))
                caps.text(t, "overlap sources", [src for src, _ in pc["overlaps"]], re.findall(r"(GS|CLV) ", m.group(6)))
                caps.numbers(t, "overlaps", [o for _, o in pc["overlaps"]], split_numbers(m.group(6)))
        else:
            m = caps.find(t, rf"reconstructed at step (\d+) inside the (\w+)-dimensional (?:GS and covariant subspaces|covariant subspace) of (.*?) {span} by least squares.*? here rms δq_\w / rms δq_\w = (.*?), and ", "step, rms check")
            if m:
                size = pc["last"] - pc["first"] + 1
                caps.text(t, "frame's step", pc["step"], m.group(1))
                caps.text(t, "step", f"{'four' if size == 4 else size}-dimensional, of {pc['family'] if pc['several'] else pc['name']}: {pc['first']}..{pc['last']}", f"{m.group(2)}-dimensional, of {m.group(3)}: {m.group(4)}..{m.group(5)}")
                caps.text(t, "rms sources", [src for src, _ in pc["rms"]], re.findall(r"(GS|CLV) ", m.group(6)))
                caps.numbers(t, "rms across / along", [r for _, r in pc["rms"]], split_numbers(m.group(6)))
            said = re.search(r"Off scale, so that the sinusoid is seen: (.*?) \(every value", caps.sections[t])
            listed = re.findall(rf"Fig\. (\d+) (L|P): (\d+) of (\d+) points beyond ({NUMBER})\.\.({NUMBER})", said.group(1)) if said else []
            caps.text(t, "figures with points off scale", [f"{fig} {which}" for fig, which, *_ in pc["off"]], [f"{fig} {which}" for fig, which, *_ in listed])
            for (fig, which, lo, hi, off, total), got in zip(pc["off"], listed):
                caps.text(t, f"Fig. {fig} {which} points off scale", f"{off} of {total}", f"{got[2]} of {got[3]}")
                caps.numbers(t, f"Fig. {fig} {which} range", [lo, hi], [got[4], got[5]])

    # Dispersion: the slope through the origin of each kind and lambda/k of each step.
    t = "Dispersion of the Lyapunov modes (beyond the paper)"
    if caps.has(t) and modes is not None and modes["modes_dispersion.csv"]:
        rows = modes["modes_dispersion.csv"]
        for kind in sorted({r["kind"] for r in rows}):
            of = [r for r in rows if r["kind"] == kind]
            ks, lam = np.array([r["k"] for r in of]), np.array([r["lambda"] for r in of])
            m = caps.find(t, rf"{kind}: c = ({NUMBER})(?: ± ({NUMBER}))? from (\d+) step\(s\), λ/k = ([^f]*?) for ", f"{kind} fit")
            if m:
                c_fit = (ks * lam).sum() / (ks**2).sum()
                caps.number(t, f"{kind} slope c", c_fit, m.group(1))
                # the slope's standard error from the scatter about the line, m - 1 degrees of freedom
                se = math.sqrt(((lam - c_fit * ks) ** 2).sum() / (len(of) - 1) / (ks**2).sum()) if len(of) >= 2 else math.nan
                caps.text(t, f"{kind} slope error given", math.isfinite(se), m.group(2) is not None)
                if m.group(2) is not None and math.isfinite(se):
                    caps.number(t, f"{kind} slope error", se, m.group(2))
                caps.text(t, f"{kind} steps", len(of), m.group(3))
                caps.numbers(t, f"{kind} lambda/k", lam / ks, split_numbers(m.group(4)))

    # Fig. 14: the largest average overlap of each positive step's last vector inside its step,
    # inside the conjugate step and elsewhere.
    t = "Scalar products of mode vectors (Fig. 14)"
    steps = [st for st, _ in f["steps"] if st[0] + st[1] <= d // 2 - 3]
    if caps.has(t) and k == d and len(steps) >= 2:  # with fewer, clv shows j = 2N-5, 2N-3 without this
        m = caps.find(t, r"inside the conjugate step and anywhere else: (.*?)\. In ", "overlaps")
        said = dict(re.findall(r"j = (\d+): ([^;]*)", m.group(1))) if m else {}
        for a, ln in steps:
            j = a + ln - 1
            mean = np.abs(np.einsum("td,tdi->ti", v[:, :, j], v)).mean(axis=0)
            own, conj = set(range(a, a + ln)), set(range(d - a - ln, d - a))
            top = lambda keep: max((mean[i] for i in range(d) if i != j and keep(i)), default=np.nan)  # noqa: E731
            mine = [top(lambda i: i in own), top(lambda i: i in conj), top(lambda i: i not in own and i not in conj)]
            if str(j + 1) not in said:
                if m:
                    caps.c.bad.append(f"disagreement: caption '{t}' j = {j + 1}: not there")
                continue
            caps.numbers(t, f"j = {j + 1} largest overlaps", mine, split_numbers(said[str(j + 1)]))

    # Fig. 15: Psi's minimum and mean, and Phi's of each positive mode step.
    t = "Transversality of conjugate subspaces (Fig. 15)"
    if caps.has(t) and f["transversality"] is not None:
        names, angles = f["transversality"]
        deg = math.degrees
        m = caps.find(t, rf"Ψ between E\^u = v\^1\.\.v\^(\d+) and E\^s = v\^(\d+)\.\.v\^(\d+) \(min ({NUMBER})° = ({NUMBER}) rad, mean ({NUMBER})° = ({NUMBER}) rad", "Psi")
        psi = angles[:, 0][np.isfinite(angles[:, 0])]
        if m:
            caps.text(t, "E^u, E^s", f"1..{2 * n - 3}, {2 * n + 4}..{4 * n}", f"1..{m.group(1)}, {m.group(2)}..{m.group(3)}")
            for what, x, group in (("min Psi (deg)", deg(psi.min()), 4), ("min Psi (rad)", psi.min(), 5), ("mean Psi (deg)", deg(psi.mean()), 6), ("mean Psi (rad)", psi.mean(), 7)):
                caps.number(t, what, x, m.group(group))
            if psi.min() > 0:
                caps.find(t, r"Ψ > 0 in every frame: E\^u and E\^s are transversal", "Psi > 0")
        for col, x in zip(names[1:], angles.T[1:]):
            a, b = col.split("_")[1:]
            x = x[np.isfinite(x)]
            m = caps.find(t, rf"Φ for [^;]*?\(i = {a}\.\.{b}\): min ({NUMBER})° \(({NUMBER}) rad\), mean ({NUMBER})° \(({NUMBER}) rad\)", f"Phi of i = {a}..{b}")
            if m:
                for what, y, group in (("min", deg(x.min()), 1), ("min rad", x.min(), 2), ("mean", deg(x.mean()), 3), ("mean rad", x.mean(), 4)):
                    caps.number(t, f"Phi i = {a}..{b} {what}", y, m.group(group))
        if len(names) == 1:
            caps.find(t, r"\(no mode steps were detected\)", "no mode steps")

    # Figs. 16, 17: F^(J), the separations, the first bin of i - j = 1 against the next four,
    # and the smallest Theta of i - j = 1.
    j = f["theta_j"]
    t = "Angles between covariant vectors (Fig. 16)"
    if caps.has(t) and j is not None and j >= 2:
        m = caps.find(t, r"pairs of covariant vectors in F\^\((\d+)\) = v\^1\.\.v\^(\d+) .*? with index separations i - j = ([\d, ]+) \(", "F^(J) and separations")
        if m:
            caps.text(t, "J", j, m.group(1))
            caps.text(t, "separations", ", ".join(map(str, theta_separations(d, j))), m.group(3).strip())
        counts, total, maybe = theta_histogram(thetas(v, 1, j))
        w = math.pi / 2 / THETA_BINS
        if not maybe[:5].any():
            density = counts / (total * w)
            mean = density[1:5].mean()
            m = caps.find(t, rf"For i - j = 1 the density in the first bin \(Θ < ({NUMBER})°\) is ({NUMBER}), against ({NUMBER}) in the next (\d+) bins: ", "first bin")
            if m:
                caps.number(t, "first bin density", density[0], m.group(2))
                caps.number(t, "next bins' density", mean, m.group(3))
                held = int(counts[:5].sum())
                if held < 50:
                    caps.find(t, rf"{held} angles in these bins are too few", "angles in the first bins")
                elif density[0] < 0.5 * mean:
                    caps.find(t, r"it falls toward Θ = 0, as the paper's", "first bin verdict")
                elif density[0] < 0.85 * mean:
                    mm = caps.find(t, rf"it dips in the first bin \(({NUMBER}) % below\)", "first bin verdict")
                    if mm:
                        caps.number(t, "first bin dip %", 100 * (1 - density[0] / mean), mm.group(1))
                else:
                    caps.find(t, r"it does not fall toward Θ = 0 here", "first bin verdict")
    t = "Minimum angle between covariant vectors (Fig. 17)"
    if caps.has(t) and j is not None and j >= 2:
        m = caps.find(t, rf"over all pairs in F\^\((\d+)\) and (\d+) frames .*?min Θ for i - j = 1: ({NUMBER}) rad", "min Theta")
        if m:
            caps.text(t, "J", j, m.group(1))
            caps.text(t, "frames", len(sampled), m.group(2))
            caps.number(t, "min Theta (i - j = 1)", thetas(v, 1, j).min(), m.group(3))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("report")
    ap.add_argument("frames")
    ap.add_argument("--blocks", type=int, help="the run's blocks setting (default: run.json's, from the frame file's metadata)")
    ap.add_argument("--run", metavar="RUN_DIR", help="the run directory of the frames: recompute lambda_gs, stderr_gs from its R_n (needs --store-r all and --clv-steps + --transient = --steps)")
    args = ap.parse_args()
    rep = lambda name: read_csv(os.path.join(args.report, name))  # noqa: E731

    if not os.path.isfile(os.path.join(args.report, "summary.json")):
        sys.exit(f"verify_report.py: {args.report} is not a finished report of `clv analyze` (no summary.json)")
    if args.run is not None:
        run_json(args.run, "verify_report.py")
    with open(os.path.join(args.report, "summary.json")) as f:
        summary = json.load(f)
    every = int(summary["options"]["every"])
    frames = load_frames(args.frames, "verify_report.py")
    d = frames[0]["phase"].size
    if d % 4:
        sys.exit(f"{args.frames}: D = {d} is not 4N: not a hard-disk run")
    n = d // 4
    meta = metadata(args.frames)
    run = meta.get("run.json", {})
    config = run.get("config", run) or {}
    forward = meta.get("spectrum.json")  # the forward GS spectrum: exponents, stderr, blocks
    if args.blocks is not None:
        blocks = args.blocks
    else:
        blocks = config.get("blocks")
        if blocks is None:
            sys.exit(f"{args.frames}: no run.json blocks setting in its metadata: give --blocks")
    blocks = int(blocks)
    c = Checker()

    # Spectrum: every frame.
    local = np.array([f["local"] for f in frames])
    sp = rep("spectrum.csv")
    if sp is not None:
        i = sp["i"].astype(int)
        c.compare("spectrum.csv", "lambda_clv", i, local.mean(axis=0)[i - 1], sp["lambda_clv"])
        c.compare("spectrum.csv", "stderr_clv", i, batch_stderr(local, blocks)[i - 1], sp["stderr_clv"], TOL_ERR)
        # The reduced index i/D (the paper's i/4N), the null space i = 2N-2..2N+3 (six
        # exponents vanish by symmetry: time and space translations, energy and momentum),
        # and the shear model's exponent of its last three CLVs over the frames' steps.
        null = (i >= 2 * n - 2) & (i <= 2 * n + 3)
        c.compare("spectrum.csv", "i_over_D", i, i / d, sp["i_over_D"])
        c.compare("spectrum.csv", "zero_by_symmetry", i, null.astype(float), sp["zero_by_symmetry"])
        total = int(config["relax_steps"]) + int(config["steps"])
        shear = null_shear_mean([f["step"] for f in frames], total, float(config["tau"]))
        c.compare("spectrum.csv", "lambda_clv_null_shear", i, np.where(i >= 2 * n + 1, shear, np.nan) * np.where(null, 1.0, np.nan), sp["lambda_clv_null_shear"])
        if all(f["gs_local"] is not None for f in frames):
            gs_local = np.array([f["gs_local"] for f in frames])
            c.compare("spectrum.csv", "lambda_gs_window", i, gs_local.mean(axis=0)[i - 1], sp["lambda_gs_window"])
            c.compare("spectrum.csv", "stderr_gs_window", i, batch_stderr(gs_local, blocks)[i - 1], sp["stderr_gs_window"], TOL_ERR)
        if forward is not None and "lambda_gs" in sp and args.run is None:  # the forward run's, as its spectrum.json has them
            c.compare("spectrum.csv", "lambda_gs", i, np.asarray(forward["exponents"], float)[i - 1], sp["lambda_gs"])
            c.compare("spectrum.csv", "stderr_gs", i, np.array([np.nan if x is None else x for x in forward["stderr"]], float)[i - 1], sp["stderr_gs"], TOL_ERR)

    # The forward GS spectrum from the run's R_n: spectrum.csv's lambda_gs and stderr_gs, the
    # run's spectrum.json and the frame file's copy of it.
    forward_r = None
    if args.run is not None:
        forward_r = forward_from_r(args.run)
        ours = {k: v for k, v in forward_r["config"].items() if k != "threads"}
        theirs = {k: v for k, v in config.items() if k != "threads"}
        if ours != theirs:
            sys.exit(f"{args.run} is not the run of {args.frames}: run.json's config {ours} there, {theirs} in the frame file")
        if sp is not None and "lambda_gs" in sp:
            i = sp["i"].astype(int)
            c.compare("spectrum.csv", "lambda_gs", i, forward_r["exponents"][i - 1], sp["lambda_gs"])
            if "stderr_gs" in sp:
                c.compare("spectrum.csv", "stderr_gs", i, forward_r["stderr"][i - 1], sp["stderr_gs"], TOL_ERR)
        path = os.path.join(args.run, "spectrum.json")
        if not os.path.exists(path):
            c.bad.append(f"disagreement: {path} is not there (the run is not finished)")
        else:
            with open(path) as f:
                compare_spectrum_json(c, "run/spectrum.json", forward_r, json.load(f))
        if forward is not None:
            compare_spectrum_json(c, "frames/spectrum.json", forward_r, forward)

    # Convergence: running means of the batch means (CLV: of every frame's local exponents;
    # GS: the forward run's block averages in spectrum.json), and their tests.
    tests = []
    sources = [(0, "convergence_gs.csv", None), (1, "convergence_clv.csv", block_means(local, blocks))]
    if forward is not None and (forward.get("blocks") or {}).get("exponents"):
        sources[0] = (0, "convergence_gs.csv", (np.asarray(forward["blocks"]["exponents"], float), int(forward["blocks"]["block_steps"])))
    tau = float(config.get("tau", np.nan))
    neutral = range(max(2 * n - 3, 0), 2 * n + 3)
    for ident, table, means in sources:
        t = rep(table)
        if means is None or t is None:
            continue
        means, length = means
        running = np.cumsum(means, axis=0) / np.arange(1, len(means) + 1)[:, None]
        rows = np.arange(1, len(means) + 1)
        if len(t.get("t", [])) != len(means):
            c.bad.append(f"disagreement: {table} has {len(t.get('t', []))} rows, mine {len(means)} blocks")
            continue
        c.compare(table, "t", rows, rows * (length * tau), t["t"])
        for col in t:
            if col.startswith("lambda_"):
                c.compare(table, col, rows, running[:, int(col[len("lambda_") :]) - 1], t[col])
        diag = diagnose(means, neutral)
        if diag is not None:
            tests.append({"spectrum_0gs_1clv": str(ident), "block_steps": float(length)} | diag)
    ct = read_rows(os.path.join(args.report, "convergence_tests.csv"))
    if ct is not None:
        c.compare_rows("convergence_tests.csv", ("spectrum_0gs_1clv",), tests, ct, lambda r: "GS" if r["spectrum_0gs_1clv"] == "0" else "CLV")

    # Local exponents, finite-time exponents and domination: every frame.
    le = rep("local_exponents.csv")
    if le is not None and len(le.get("step", [])):
        steps = np.array([f["step"] for f in frames])
        rows = np.searchsorted(steps, le["step"].astype(np.int64))
        if np.any(rows >= len(frames)) or np.any(steps[np.minimum(rows, len(frames) - 1)] != le["step"]):
            c.bad.append("disagreement: local_exponents.csv has steps that are not frames")
            rows = np.minimum(rows, len(frames) - 1)
        idx = le["step"].astype(np.int64)
        c.compare("local_exponents.csv", "time", idx, np.array([frames[r]["time"] for r in rows]), le["time"])
        for col in le:
            if col.startswith("lambda_"):
                c.compare("local_exponents.csv", col, idx, local[rows, int(col[len("lambda_") :]) - 1], le[col])
    ft = rep("finite_time_exponents.csv")
    if ft is not None and len(ft.get("i", [])):
        for col in ("windows", "mean", "std", "min", "max"):
            mine = []
            for i, delta in zip(ft["i"].astype(int), ft["delta"].astype(int)):
                x = windows(local, delta)[:, i - 1]
                mine.append({"windows": len(x), "mean": x.mean(), "std": sample_std(x[:, None])[0], "min": x.min(), "max": x.max()}[col])
            c.compare("finite_time_exponents.csv", col, ft["i"].astype(int), mine, ft[col])
    dm = rep("domination.csv")
    if dm is not None and len(dm.get("delta", [])):
        deltas = dm["delta"].astype(int)
        mine = {}
        for delta in deltas:
            for col, value in domination(window_sums(local, delta), n).items():
                mine.setdefault(col, []).append(value)
        for col in dm:
            if col in mine:
                c.compare("domination.csv", col, deltas, mine[col], dm[col])
            elif col != "delta":
                c.bad.append(f"disagreement: domination.csv column {col} is not recomputed here")

    dp = rep("domination_pairs.csv")
    if dp is not None and len(dp.get("i", [])):
        pairs = dp["i"].astype(int)
        if list(pairs) != list(range(1, local.shape[1])):
            c.bad.append(f"disagreement: domination_pairs.csv pairs i = {pairs.min()}..{pairs.max()} ({len(pairs)} rows), mine 1..{local.shape[1] - 1}")
        else:
            for col in dp:
                if not col.startswith("delta_"):
                    if col != "i":
                        c.bad.append(f"disagreement: domination_pairs.csv column {col} is not recomputed here")
                    continue
                x = window_sums(local, int(col[len("delta_") :]))
                # the share of the windows in which exponent i + 1 exceeds exponent i
                swaps = (x[:, 1:] > x[:, :-1]).sum(axis=0) / len(x) if len(x) else np.full(len(pairs), np.nan)
                c.compare("domination_pairs.csv", col, pairs, swaps[pairs - 1], dp[col])

    # Vector statistics: the frames of the steps that are multiples of m.
    sampled = [f for f in frames if f["step"] % every == 0 and f["v"] is not None]
    if not sampled:
        sys.exit(f"{args.frames}: no frame with vectors at a multiple of {every}")
    vecs = {"clv": np.array([f["v"] for f in sampled])}
    if all(f["g"] is not None for f in sampled):
        vecs["gs"] = np.array([f["g"] for f in sampled])

    loc, pr = rep("localization.csv"), rep("projections.csv")
    for name, x in vecs.items():
        if loc is not None:
            i = loc["i"].astype(int)
            w, err = localization(x, n, blocks)
            c.compare("localization.csv", f"W_{name}", i, w[i - 1], loc[f"W_{name}"])
            if f"stderr_{name}" in loc:
                c.compare("localization.csv", f"stderr_{name}", i, err[i - 1], loc[f"stderr_{name}"], TOL_ERR)
        if pr is not None:
            i = pr["i"].astype(int)
            means, per_frame = projections(x, n)
            for col, mine in means.items():
                c.compare("projections.csv", f"{col}_{name}", i, mine[i - 1], pr[f"{col}_{name}"])
            for col, values in per_frame.items():  # eta_q_gs_std (eta_p_*_std where the report has it)
                if f"{col}_{name}_std" in pr:
                    c.compare_std("projections.csv", f"{col}_{name}_std", i, values, pr[f"{col}_{name}_std"])

    if "gs" not in vecs:  # frames without GS vectors: their columns must be NaN throughout
        for table, t in (("localization.csv", loc), ("projections.csv", pr)):
            for col in [col for col in t or {} if col.endswith(("_gs", "_gs_std"))]:
                c.compare(table, col, t["i"].astype(int), np.nan, t[col])

    v, g = vecs["clv"], vecs.get("gs")
    ov = rep("overlap_gs_clv.csv")
    if ov is not None and g is not None:
        i = ov["i"].astype(int)
        a = np.abs(np.einsum("tdi,tdi->ti", g, v))
        c.compare("overlap_gs_clv.csv", "abs_g_dot_v_mean", i, a.mean(axis=0)[i - 1], ov["abs_g_dot_v_mean"])
        if "abs_g_dot_v_std" in ov:
            c.compare_std("overlap_gs_clv.csv", "abs_g_dot_v_std", i, a, ov["abs_g_dot_v_std"])
    for table, other in (("overlap_clv_gs.csv", g), ("overlap_clv_clv.csv", v)):
        ov = rep(table)
        if ov is None or other is None:
            continue
        i = ov["i"].astype(int)
        for col in ov:
            if col.startswith("abs_v") and col.endswith("_mean"):
                j = int(col[len("abs_v") : -len("_mean")])
                a = np.abs(np.einsum("td,tdi->ti", v[:, :, j - 1], other))
                c.compare(table, col, i, a.mean(axis=0)[i - 1], ov[col])
                if f"abs_v{j}_std" in ov:
                    c.compare_std(table, f"abs_v{j}_std", i, a, ov[f"abs_v{j}_std"])

    # Null space at the earliest sampled frame (sampled is in increasing step order).
    e = natural_basis(sampled[0]["phase"], n)
    for table, x in (("nullspace_alpha.csv", g), ("nullspace_beta.csv", v)):
        t = rep(table)
        if t is None or x is None:
            continue
        i = t["i"].astype(int)
        mine = x[0][:, i - 1].T @ e
        for k in range(6):
            c.compare(table, f"e{k + 1}", i, mine[:, k], t[f"e{k + 1}"])
        c.compare(table, "row_norm", i, np.linalg.norm(mine, axis=1), t["row_norm"])

    # The same matrices in nullspace_tables.json, with the frame they are taken at.
    null = np.arange(2 * n - 3, 2 * n + 3)  # 0-based 2N-3..2N+2: the paper's 2N-2..2N+3
    path = os.path.join(args.report, "nullspace_tables.json")
    if os.path.exists(path) and v.shape[2] >= 2 * n + 3:
        with open(path) as f:
            table = json.load(f)
        at = sampled[0]
        head = {"n": str(n), "indices": ",".join(str(k + 1) for k in null), "step": str(at["step"]), "time": at["time"]}
        cell = lambda x: ",".join(map(str, x)) if isinstance(x, list) else str(x) if isinstance(x, int) else x  # noqa: E731
        # note: a fixed text, not a number of the frames; alpha, beta: the rows below
        c.compare_rows("nullspace_tables.json", (), [head], [{k: cell(x) for k, x in table.items() if k not in ("note", "alpha", "beta")}], lambda r: "head")
        mine, theirs = [], []
        for name, x in (("beta", v), ("alpha", g)):
            if table.get(name) is None and x is None:
                continue
            if x is not None:
                proj = x[0][:, null].T @ e
                mine += [{"matrix": name, "i": str(k + 1)} | {f"e{c_ + 1}": proj[r, c_] for c_ in range(6)} for r, k in enumerate(null)]
            theirs += [{"matrix": name, "i": str(k + 1)} | {f"e{c_ + 1}": str(y) for c_, y in enumerate(row)} for k, row in zip(null, table.get(name) or [])]
        c.compare_rows("nullspace_tables.json", ("matrix", "i"), mine, theirs, lambda r: f"{r['matrix']} i = {r['i']}")

    def by_step(table, report_steps):
        """The positions in `sampled` of a table's rows by their steps (None, and a
        disagreement, unless the rows are the sampled frames, each once)."""
        position = {f["step"]: r for r, f in enumerate(sampled)}
        steps_ = [int(s) for s in report_steps]
        if sorted(steps_) != sorted(position):
            c.bad.append(f"disagreement: {table} has the {len(steps_)} rows of steps {min(steps_, default=None)}..{max(steps_, default=None)}, mine the {len(position)} sampled frames of steps {sampled[0]['step']}..{sampled[-1]['step']}")
            return None
        return [position[s] for s in steps_]

    # Null space in every sampled frame: the largest principal angle between the span of the
    # six null-space vectors and span{e_1..e_6} (CLV, GS) and between the two spans, and the
    # row norms of beta and alpha.
    ns = rep("nullspace_series.csv")
    if ns is not None and len(ns.get("step", [])) and v.shape[2] >= 2 * n + 3:
        rows = by_step("nullspace_series.csv", ns["step"])
        if rows is not None:
            step = ns["step"].astype(np.int64)
            mine = {"time": [], "angle_clv": [], "angle_gs": [], "angle_gs_clv": []} | {f"norm_{m}_{k + 1}": [] for m in ("beta", "alpha") for k in null}
            for r in rows:
                f = sampled[r]
                basis = natural_basis(f["phase"], n)
                mine["time"].append(f["time"])
                mine["angle_clv"].append(principal_angle_range(f["v"][:, null], basis)[1])
                gs_null = None if f["g"] is None else f["g"][:, null]
                mine["angle_gs"].append(np.nan if gs_null is None else principal_angle_range(gs_null, basis)[1])
                mine["angle_gs_clv"].append(np.nan if gs_null is None else principal_angle_range(gs_null, f["v"][:, null])[1])
                for m, x in (("beta", f["v"]), ("alpha", f["g"])):
                    norms = np.full(6, np.nan) if x is None else np.linalg.norm(x[:, null].T @ basis, axis=1)
                    for k, norm in zip(null, norms):
                        mine[f"norm_{m}_{k + 1}"].append(norm)
            for col in ns:
                if col in mine:
                    c.compare("nullspace_series.csv", col, step, mine[col], ns[col])
                elif col != "step":
                    c.bad.append(f"disagreement: nullspace_series.csv column {col} is not recomputed here")

    # Lyapunov modes: the steps resolved at the newest sampled frame (the first clv reads:
    # the backward pass runs backward in time), classified in every sampled frame.
    steps, ambiguous = [], 0
    system = config.get("system", {})
    first = sampled[-1]
    full = forward is not None and len(forward.get("exponents", [])) == d and v.shape[2] == d and d >= 8 and "lx" in system
    if full:
        mine, steps = mode_tables(sampled, first, forward, float(system["lx"]), float(system["ly"]), d)
    else:  # clv writes an empty mode table (and says why)
        mine = {"modes.csv": [], "modes_fits.csv": [], "modes_lp.csv": [], "modes_dispersion.csv": [], "patterns": {}, "pattern_captions": []}
    modes = mine if full else None
    span = lambda r: f"i = {r['first']}..{r['last']}"  # noqa: E731
    mt = read_rows(os.path.join(args.report, "modes.csv"))
    if mt is not None:
        c.compare_rows("modes.csv", ("first", "last"), mine["modes.csv"], mt, span)
    if os.path.exists(os.path.join(args.report, "modes.json")):
        with open(os.path.join(args.report, "modes.json")) as f:
            table = json.load(f)
        cell = lambda x: str(x).lower() if isinstance(x, bool) else "" if x is None else str(x) if isinstance(x, (int, str)) else x  # noqa: E731
        c.compare_rows("modes.json", ("first", "last"), mine["modes.csv"], [{k: cell(x) for k, x in r.items()} for r in table.get("modes", [])], span)
        if full:  # the settings and candidates it lists beside the rows
            theirs = {k: ",".join(x) if isinstance(x, list) else x for k, x in table.items() if k in mine["modes.json"] and k != "other_steps"}
            theirs["other_steps"] = ";".join(f"{o['first']}..{o['last']}:{o['frames']}" for o in table.get("other_steps", []))
            c.compare_rows("modes.json", (), [mine["modes.json"]], [theirs], lambda r: "head")
    mf = read_rows(os.path.join(args.report, "modes_fits.csv"))
    if mf is not None or mine["modes_fits.csv"]:
        c.compare_rows("modes_fits.csv", ("first", "last", "i", "source", "scope"), mine["modes_fits.csv"], mf or [], lambda r: f"i = {r['i']} {r['source']} {r['scope']}")
    ml = read_rows(os.path.join(args.report, "modes_lp.csv"))
    if ml is not None or mine["modes_lp.csv"]:
        ml = ml or []
        keys = ("first", "last", "source", "figure", "pattern")
        by_key = {tuple(m[k] for k in keys): m for m in mine["modes_lp.csv"]}
        for r in ml:  # a phase is an angle in (-pi, pi]: -pi + 1e-16 and pi are the same one
            m = by_key.get(tuple(r[k] for k in keys))
            if m is not None and abs(m["phase"] - float(r["phase"])) > math.pi:
                m["phase"] -= math.copysign(2 * math.pi, m["phase"] - float(r["phase"]))
        c.compare_rows("modes_lp.csv", keys, mine["modes_lp.csv"], ml, lambda r: f"i = {r['first']}..{r['last']} {r['source']} Fig. {r['figure']} {r['pattern']}")
    md = read_rows(os.path.join(args.report, "modes_dispersion.csv"))
    if md is not None or mine["modes_dispersion.csv"]:
        numbered = lambda rows: [{"row": str(r)} | x for r, x in enumerate(rows, 1)]  # noqa: E731
        c.compare_rows("modes_dispersion.csv", ("row",), numbered(mine["modes_dispersion.csv"]), numbered(md or []), lambda r: r["name"])
    written = {t for p in summary.get("produced", []) for t in p.get("tables", []) if re.fullmatch(r"(fig10_T|LP)\d+(_m?\d+)?_i\d+\.csv", t)}
    for table in sorted(written | set(mine["patterns"])):
        cols = mine["patterns"].get(table)
        t = read_rows(os.path.join(args.report, table)) if table in written else None
        if cols is None or t is None:
            c.bad.append(f"disagreement: {table} is {'not recomputed here' if cols is None else 'not in the report'}")
            continue
        rows = [{"row": str(r + 1)} | {k: x[r] for k, x in cols.items()} for r in range(len(next(iter(cols.values()))))]
        c.compare_rows(table, ("row",), rows, [{"row": str(r)} | x for r, x in enumerate(t, 1)], lambda r: f"disk {r['row']}")

    # Fig. 15 in every sampled frame: Psi, the smallest principal angle between
    # E^u = v^1..v^m and E^s = v^(D-m+1)..v^D (m = 2N - 3), and Phi, the smallest between
    # each positive mode step (resolved above) and its conjugate vectors D+1-i.
    transversality = None
    tr = read_rows(os.path.join(args.report, "transversality.csv"))
    if tr is not None and v.shape[2] == d:
        cols = list(tr[0]) if tr else []
        phis = [st for st, _ in steps if st[0] + st[1] <= d // 2 - 3]
        names = ["psi_unstable_stable"] + [f"phi_{a + 1}_{a + ln}" for a, ln in phis]
        for col in cols:
            if col != "step" and col not in names:
                c.bad.append(f"disagreement: transversality.csv column {col} is not recomputed here")
        for col in names:
            if col not in cols:
                c.bad.append(f"disagreement: transversality.csv lacks a column mine has ({col})")
        rows = by_step("transversality.csv", [r["step"] for r in tr]) if tr else None
        if rows is not None:
            step = np.array([int(r["step"]) for r in tr])
            m = d // 2 - 3
            blocks_ = [(0, m)] + phis  # (start, length), 0-based; the conjugate of i is D-1-i
            mine = np.array([[principal_angle_range(sampled[r]["v"][:, a : a + ln], sampled[r]["v"][:, d - a - ln : d - a])[0] for a, ln in blocks_] for r in rows])
            for col, x in zip(names, mine.T):
                if col in cols:
                    c.compare("transversality.csv", col, step, x, np.array([float(r[col]) for r in tr]))
            transversality = (names, mine)

    # Figs. 16-17: Theta over the pairs of F^(J), J as clv chooses it (before the first
    # positive mode step): min and mean per separation, and the histograms of Fig. 16.
    j = f_size(d, [st for st, _ in steps]) if v.shape[2] == d else None
    tm = rep("theta_min.csv")
    if tm is not None and len(tm.get("separation", [])):
        seps = tm["separation"].astype(int)
        if j is not None and list(seps) != list(range(1, j)):
            c.bad.append(f"disagreement: theta_min.csv separations {seps.min()}..{seps.max()}, mine 1..{j - 1} (J = {j})")
        else:
            mins, means = [], []
            for s in seps:
                theta = thetas(v, s, seps.max() + 1)
                mins.append(theta.min())
                means.append(theta.mean())
            c.compare("theta_min.csv", "min_theta", seps, mins, tm["min_theta"])
            c.compare("theta_min.csv", "mean_theta", seps, means, tm["mean_theta"])
    th = rep("theta_histograms.csv")
    if th is not None and j is not None:
        width = math.pi / 2 / THETA_BINS
        bins = np.arange(1, THETA_BINS + 1)
        c.compare("theta_histograms.csv", "theta_lo", bins, (bins - 1) * width, th["theta_lo"])
        c.compare("theta_histograms.csv", "theta_hi", bins, bins * width, th["theta_hi"])
        seps = theta_separations(d, j)
        if sorted(int(col[len("density_sep_") :]) for col in th if col.startswith("density_sep_")) != seps:
            c.bad.append(f"disagreement: theta_histograms.csv separations {[col for col in th if col.startswith('density_sep_')]}, mine {seps}")
        for s in seps:
            col = f"density_sep_{s}"
            if col not in th:
                continue
            counts, total, maybe = theta_histogram(thetas(v, s, j))
            ambiguous += int(maybe.sum()) // 2
            # clv's density: count / (total * width); its counts back, to compare where an
            # angle at a bin edge could have gone either way
            theirs = th[col] * total * width
            near = maybe > 0
            c.compare("theta_histograms.csv", col, bins[~near], counts[~near] / (total * width), th[col][~near])
            for b in np.flatnonzero(near):
                if not (counts[b] - 1e-6 <= theirs[b] <= counts[b] + maybe[b] + 1e-6):
                    c.bad.append(f"disagreement: theta_histograms.csv {col} {b + 1} mine {counts[b]}..{counts[b] + maybe[b]} angles report {theirs[b]!r}")

    if not c.checked:
        sys.exit(f"{args.report}: none of the tables this script checks is there")
    # The captions of index.html: their numbers against the recomputation above.
    sections = caption_sections(os.path.join(args.report, "index.html"))
    caps = Captions(c, sections or {})
    if sections is None:
        c.bad.append(f"disagreement: {args.report}/index.html is not there")
    else:
        steps_ = [fr["step"] for fr in frames]
        total = int(config.get("relax_steps", 0)) + int(config.get("steps", 0))
        run_exponents, run_stderr, run_block_means = None, None, None
        if forward_r is not None:
            run_exponents, run_stderr, run_block_means = forward_r["exponents"], forward_r["stderr"], np.asarray(forward_r["block_means"], float)
        elif forward is not None:
            run_exponents = np.asarray(forward["exponents"], float)
            run_stderr = np.array([np.nan if x is None else x for x in forward["stderr"]], float)
            if (forward.get("blocks") or {}).get("exponents"):
                run_block_means = np.asarray(forward["blocks"]["exponents"], float)
        run_h_err = np.nan
        if run_exponents is not None:
            positive = [i for i, x in enumerate(run_exponents) if x > 0 and not 2 * n - 3 <= i < 2 * n + 3]
            if run_block_means is not None and len(run_block_means) >= 2:  # the per-block sums' standard error
                run_h_err = sample_std(run_block_means[:, positive].sum(axis=1)[:, None])[0] / math.sqrt(len(run_block_means))
            elif forward is not None and forward.get("ks_entropy"):
                run_h_err = forward["ks_entropy"].get("stderr") or np.nan
        check_captions(c, caps, {
            "n": n, "d": d, "k": local.shape[1], "blocks": blocks, "frames": len(frames), "local": local,
            "gs_local": np.array([fr["gs_local"] for fr in frames]) if all(fr["gs_local"] is not None for fr in frames) else None,
            "forward": forward, "config": config, "forward_exponents": run_exponents, "forward_stderr": run_stderr, "forward_h_ks_stderr": run_h_err,
            "shear": None if "tau" not in config else ((total - steps_[-1]) * tau - tau, (total - steps_[0]) * tau, null_shear_mean(steps_, total, tau), len(steps_) == steps_[-1] - steps_[0] + 1),
            "tests": tests, "sampled": sampled, "v": v, "g": g, "report": args.report, "deltas": [int(x) for x in summary["options"].get("deltas", [])],
            "modes": modes, "lx": float(system.get("lx", np.nan)), "ly": float(system.get("ly", np.nan)), "first_step": first["step"],
            "steps": steps, "transversality": transversality, "theta_j": j,
        })
    # Every row and column of the tables compared column by column above: the rows are
    # named by their keys, which the comparisons take from the report itself.
    k = local.shape[1]
    for table in ("spectrum.csv", "localization.csv", "projections.csv", "overlap_gs_clv.csv", "overlap_clv_gs.csv", "overlap_clv_clv.csv"):
        t = rep(table)
        if t is None or table not in c.columns:
            continue
        c.expect_keys(table, t["i"].astype(int), range(1, k + 1))
        if "i_over_D" in t and "i_over_D" not in c.columns[table]:
            i = t["i"].astype(int)
            c.compare(table, "i_over_D", i, i / d, t["i_over_D"])
        c.expect_columns(table, t, ("i",))
    if le is not None and "local_exponents.csv" in c.columns:
        c.expect_keys("local_exponents.csv", le["step"].astype(np.int64), sorted(f["step"] for f in frames))
        c.expect_columns("local_exponents.csv", le, ("step",))
    if ft is not None and le is not None and "finite_time_exponents.csv" in c.columns:
        # The indices of the local exponents' table (the chosen ones), each with every Delta.
        js, deltas = [int(col[len("lambda_") :]) for col in le if col.startswith("lambda_")], summary["options"].get("deltas", [])
        c.expect_keys("finite_time_exponents.csv", zip(ft["i"].astype(int), ft["delta"].astype(int)), [(j, dl) for j in js for dl in deltas])
        c.expect_columns("finite_time_exponents.csv", ft, ("i", "delta"))

    print(json.dumps({"agree": not c.bad, "checked": c.checked, "checked_std": c.checked_std, "columns": c.columns, "frames": len(frames), "sampled": len(sampled), "every": every, "blocks": blocks, "tolerance": TOL, "tolerance_errors": TOL_ERR, "mode_steps": [[st[0] + 1, st[0] + st[1], how] for st, how in steps], "theta_j": j, "theta_at_bin_edges": ambiguous, "captions": caps.checked}
                     | ({} if forward_r is None else {"forward_r": {k: forward_r[k] for k in ("steps", "block_steps", "planned_block_steps", "plan_from")} | {"blocks": len(forward_r["block_means"])}})))
    if c.bad:
        for line in c.bad:
            print(line, file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
