// Convergence in the time step: the `converges` claim rule (core/claims.h lists it among the
// kinds), which decides whether runs at a longer drive step (core/numerics.h) give Table 1's U_z.
//
// Rule: {"kind": "converges", "reference": [sweeps at the reference step], "sweeps": [sweeps at
// other steps], "margin_rel": 0.10, "margin_abs_mps": 0.005}. The margin is fixed in the campaign
// file before any run: it is what "the same U_z" means, delta = max(margin_rel |U_ref|,
// margin_abs_mps), U_ref the point's mean over its reference beds. The defaults, 10 % of |U_z| or
// 5 mm/s, are half of what one smoke run resolves (its precision target: 20 % or 5 mm/s) and
// about half the bed-to-bed scatter the paper's claims must see through (smoke's prior, 17 %).
//
// Pairing. A run of a compared sweep is paired with the reference run of the same drive (every
// field but the step) on the same replicate bed: the bed's packing, which moves U_z by more than a
// step might, is shared and cancels from d = U(dt) - U(ref). A point at a step needs every one of
// its beds measured at both steps (core/claims.h "measured"); else it is missing, with why.
//
// Decision per point and step, on the K paired differences d_k:
//   d = mean d_k; its standard error the larger of the runs' own (sqrt(sum se_a^2 + se_b^2) / K,
//   Welch-Satterthwaite degrees of freedom from each run's interval, core/aggregate.h
//   DofOfInterval) and, for K >= 2, the pairs' scatter (sd(d_k) / sqrt K, K - 1 dof);
//   equivalent  both one-sided tests at 5 %: the 90 % interval of d inside (-delta, +delta);
//   differs     the 95 % interval of d wholly outside [-delta, +delta] (the step moves U_z by more
//               than the margin);
//   else        inconclusive (lack of power, never a verdict).
// A step's part holds (equivalent) when every point of it is, differs when one point differs, else
// is inconclusive; the claim holds when every step's part holds (an intersection-union test: its
// false "holds" is at most 5 % however many points), and says "converged up to dt = X": the longest
// step whose part holds, with every shorter step's holding too. The z amplitude at f is shown
// beside U_z (means over the beds at both steps); it has no error and decides nothing.
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_CONVERGENCE_H_
#define SANDSWIM_CORE_CONVERGENCE_H_

#include "core/claims.h"

namespace sandswim {

inline constexpr double kDefaultMarginRel = 0.10;
inline constexpr double kDefaultMarginAbsMps = 0.005;

// Fills `v` (parts, missing, verdict, reason) for a claim of kind "converges".
void EvaluateConvergence(const Claim& c, const ClaimInput& in, ClaimVerdict& v);
// "converged up to dt = 5e-05 s", or that no longer step was shown equivalent: from the parts
// EvaluateConvergence made (ascending steps).
std::string ConvergedUpTo(const ClaimVerdict& v);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_CONVERGENCE_H_
