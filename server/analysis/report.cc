#include "server/analysis/report.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <ctime>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <tuple>

#include "core/job_state.h"
#include "core/branch.h"
#include "core/aggregate.h"
#include "core/scale.h"
#include "core/sweep.h"
#include "core/text.h"
#include "core/trajectory.h"
#include "server/analysis/claim_check.h"
#include "server/store/snapshot_files.h"

namespace sandswim {
namespace {

std::string Escape(const std::string& text) {
  std::string out;
  for (char ch : text) {
    switch (ch) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += ch;
    }
  }
  return out;
}

std::string PlusMinus(double v, double err) { return Num(v, 4) + " ± " + Num(err, 2); }

std::string UtcTime(double unix_s) {
  std::time_t t = static_cast<std::time_t>(unix_s);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%d %H:%M:%S UTC", &tm);
  return buf;
}

// An SVG file's <svg> element alone (no XML prolog or DOCTYPE), for inlining in HTML. PLplot
// names its clip paths alike in every file ("text-clipping0"); inlined together they would
// clash, so each figure's ids (and the url(#...) references to them) get a prefix of their own.
std::string InlineSvg(const std::string& svg, const std::string& prefix) {
  size_t at = svg.find("<svg");
  if (at == std::string::npos) return std::string();
  static const std::regex kIds(R"re((\sid="|url\(#|href="#))re");
  return std::regex_replace(svg.substr(at), kIds, "$1" + prefix + "-");
}

// In place of a figure that could not be drawn: the reason, as a small SVG of text.
std::string NotDrawnSvg(const std::string& why) {
  return "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"900\" height=\"40\"><text x=\"8\" y=\"25\" "
         "fill=\"#a00\">figure not drawn: " +
         Escape(why) + "</text></svg>";
}

std::string FigureHtml(const std::string& svg, const std::string& id, const std::string& caption,
                       const std::string& why_none = "nothing finished yet") {
  if (svg.empty()) return "<p class=\"none\">" + Escape(caption) + ": " + Escape(why_none) + ".</p>\n";
  return "<figure>" + InlineSvg(svg, id) + "<figcaption>" + Escape(caption) + "</figcaption></figure>\n";
}

std::string FitRows(const ReportSweep& s) {
  std::string rows;
  const SweepFits& fits = s.fits;
  if (fits.choice.kind == FitKind::kNone || fits.branches.empty()) {
    return "<tr><td><a href=\"#sweep-" + std::to_string(s.info.id) + "\">" + Escape(s.info.name) +
           "</a></td><td>none</td><td colspan=\"5\">" +
           Escape(fits.choice.kind == FitKind::kNone ? fits.choice.reason
                  : fits.left_out.empty()            ? std::string("no finished runs")
                                                     : "no conclusive runs: " + std::to_string(fits.left_out.size()) +
                                                " finished run(s) left out as inconclusive") +
           "</td></tr>\n";
  }
  // Inconclusive runs are not fitted: say which, under the sweep's first row.
  std::string left_out;
  if (!fits.left_out.empty()) {
    left_out = "<br><small>left out, inconclusive: ";
    for (size_t i = 0; i < fits.left_out.size(); ++i) {
      left_out += (i ? ", " : "") + std::string("<a href=\"#run-") + std::to_string(fits.left_out[i].run_id) +
                  "\">run " + std::to_string(fits.left_out[i].run_id) + "</a>";
    }
    left_out += "</small>";
  }
  for (const BranchFit& b : fits.branches) {
    std::string law, params, r2, range, signs = b.sign_matches_paper ? (*b.sign_matches_paper ? "yes" : "NO") : "–";
    if (b.saturation) {
      law = "eq. 8: U<sub>z</sub> = ±C1 (1 − e<sup>−C2|Ω|</sup>)";
      params = "C1 = " + PlusMinus(b.saturation->c1, b.saturation->c1_stderr) +
               " m/s<br>C2 = " + PlusMinus(b.saturation->c2, b.saturation->c2_stderr) + " s/rad";
      r2 = Num(b.saturation->r2, 3);
      range = std::to_string(b.saturation->n) + " points" + (b.saturation->weighted ? ", weighted" : ", unweighted");
    } else if (b.linear) {
      law = "eq. 9: U<sub>z</sub> = C3 A";
      params = "C3 = " + PlusMinus(b.linear->c3, b.linear->c3_stderr) + " 1/s";
      r2 = Num(b.linear->r2, 3);
      range = "A = " + Num(b.linear->a_from, 4) + " … " + Num(b.linear->a_to, 4) + " m (" +
              std::to_string(b.linear->n) + " of " + std::to_string(b.linear->n_total) + " points" +
              (b.linear->weighted ? ", weighted" : ", unweighted") + ")";
    } else if (b.fastest_rise) {
      law = "fastest rise";
      params = "f<sub>c</sub> = " + Num(b.fastest_rise->f_c, 4) + " Hz, interval [" +
               Num(b.fastest_rise->interval_lo, 4) + ", " + Num(b.fastest_rise->interval_hi, 4) + "] Hz" +
               (b.fastest_rise->at_edge ? " (at the edge)" : "");
      r2 = "–";
      range = std::to_string(b.fastest_rise->n) + " points";
    } else {
      law = FitKindName(fits.choice.kind);
      params = "not fitted: " + Escape(b.error);
    }
    rows += "<tr><td><a href=\"#sweep-" + std::to_string(s.info.id) + "\">" + Escape(s.info.name) + "</a> (" +
            Escape(b.branch) + ")" + (&b == &fits.branches.front() ? left_out : "") + "</td><td>" + law + "</td><td>" +
            params + "</td><td>" + r2 + "</td><td>" + range + "</td><td>" + signs + "</td><td>" +
            std::to_string(b.points) + "</td></tr>\n";
  }
  return rows;
}

// What "drifted" means in a report, and how often it is said when nothing changed.
std::string DriftRuleHtml(const DriftReport& drift) {
  std::string text = "Drift rule " + std::to_string(drift.rule) + ": ";
  text += drift.rule >= 2 ? "a run's change is held to the 95 % bound of the difference of its two rates (Student t, "
                            "Welch's degrees of freedom), a point's to that of its beds' mean change, and the campaign "
                            "drifted when a point did at family-wise 5 % (Holm)"
                          : "a change is held to 1.96 times the error of the difference";
  if (drift.tolerance_mps > 0) text += ", and to the campaign's tolerance";
  text += ".";
  if (!drift.false_alarms.empty()) text += " " + drift.false_alarms + ".";
  return "<p class=\"rule\">" + Escape(text) + "</p>\n";
}

std::string DriftHtml(const std::optional<DriftReport>& drift) {
  if (!drift) return "<p class=\"none\">No drift report yet: one is made when a campaign run finishes.</p>\n";
  std::string html = "<p>" + Escape(drift->summary) + "</p>\n" + DriftRuleHtml(*drift) +
                     "<table><tr><th>run</th><th>point</th><th>state</th>"
                     "<th>U<sub>z</sub> (m/s)</th><th>before (m/s)</th><th>difference (m/s)</th><th></th></tr>\n";
  auto cell = [](const std::optional<double>& v) { return v ? Num(*v, 4) : std::string("–"); };
  for (const DriftPoint& p : drift->rows) {
    // An inconclusive rate is never compared: no number that looks like one is shown for it.
    const std::string now = p.inconclusive ? "inconclusive" : cell(p.uz);
    const std::string note = p.drifted             ? "drifted"
                             : p.estimator_changed ? "not compared: U_z analysis changed"
                             : p.reused            ? "reused"
                                                   : "";
    html += "<tr" + std::string(p.drifted ? " class=\"drifted\"" : "") + "><td><a href=\"#run-" +
            std::to_string(p.run_id) + "\">" + std::to_string(p.run_id) + "</a></td><td>" + Escape(p.point.dump()) +
            "</td><td>" + Escape(ToString(p.state)) + "</td><td>" + now + "</td><td>" + cell(p.uz_previous) + "</td><td>" +
            cell(p.difference) + "</td><td>" + note + "</td></tr>\n";
  }
  html += "</table>\n";
  // Points run on several beds: their means over the beds, compared with their errors.
  bool replicated = false;
  for (const DriftAggregate& a : drift->aggregates) replicated = replicated || a.replicates > 1;
  if (!replicated) return html;
  html +=
      "<p>Each point over its replicate beds (mean ± standard error; the difference is its beds' mean change, each "
      "bed against itself, held to the tolerance shown):</p>\n"
      "<table><tr><th>point</th><th>beds</th><th>mean U<sub>z</sub> (m/s)</th><th>before (m/s)</th>"
      "<th>difference (m/s)</th><th>tolerance (m/s)</th><th></th></tr>\n";
  auto mean = [&](const std::optional<double>& m, const std::optional<double>& se, int conclusive, int beds) {
    return cell(m) + (se ? " ± " + Num(*se, 4) : std::string()) + " (" + std::to_string(conclusive) + "/" +
           std::to_string(beds) + ")";
  };
  // A point without a mean now: why, from its runs (failed, unfinished, or done but inconclusive).
  auto no_mean = [&](const nlohmann::json& point) {
    int failed = 0, unfinished = 0, inconclusive = 0;
    for (const DriftPoint& p : drift->rows) {
      if (p.point != point) continue;
      if (p.state == JobState::kFailed || p.state == JobState::kCancelled) {
        ++failed;
      } else if (p.state != JobState::kDone) {
        ++unfinished;
      } else {
        ++inconclusive;
      }
    }
    std::vector<std::string> parts;
    if (failed > 0) parts.push_back(std::to_string(failed) + " failed");
    if (unfinished > 0) parts.push_back(std::to_string(unfinished) + " not finished");
    if (inconclusive > 0) parts.push_back(std::to_string(inconclusive) + " inconclusive");
    std::string text = "no mean";
    for (size_t i = 0; i < parts.size(); ++i) text += (i == 0 ? ": " : ", ") + parts[i];
    return text;
  };
  for (const DriftAggregate& a : drift->aggregates) {
    const std::string note = a.drifted             ? "drifted"
                             : a.estimator_changed ? "not compared: U_z analysis changed"
                             : !a.uz_mean_previous ? "no earlier mean"
                             : !a.tolerance        ? "not compared: no error"
                                                   : "";
    html += "<tr" + std::string(a.drifted ? " class=\"drifted\"" : "") + "><td>" + Escape(a.point.dump()) +
            "</td><td>" + std::to_string(a.replicates) + "</td><td>" +
            (a.uz_mean ? mean(a.uz_mean, a.uz_stderr, a.conclusive, a.replicates) : no_mean(a.point)) + "</td><td>" +
            (a.uz_mean_previous
                 ? mean(a.uz_mean_previous, a.uz_stderr_previous, a.conclusive_previous, a.replicates_previous)
                 : std::string("–")) +
            "</td><td>" + cell(a.difference) + "</td><td>" + cell(a.tolerance) + "</td><td>" + note + "</td></tr>\n";
  }
  return html + "</table>\n";
}

// What the paper reports: its text, then its numbers ("A_m = 0.03").
std::string PaperHtml(const nlohmann::json& paper) {
  const std::string numbers = DescribePaperNumbers(paper);
  return Escape(paper.value("text", "")) + (numbers.empty() ? "" : "<br><small>" + Escape(numbers) + "</small>");
}

std::string VerdictHtml(Verdict v) {
  return std::string("<span class=\"") + VerdictName(v) + "\">" + VerdictName(v) + "</span>";
}

// A verdict's error rates at its design (core/claim_rates.h): "false holds <= x %, ..." or "not
// calibrated at this design", and what would help, marked when its power is low.
std::string RatesHtml(const std::optional<ClaimRates>& r) {
  if (!r) return "";
  const char* cls = !r->calibrated ? "rates uncalibrated" : r->low_power ? "rates low-power" : "rates";
  return std::string("<br><small class=\"") + cls + "\">" + Escape(r->text) +
         (r->advice.empty() ? std::string() : " &mdash; " + Escape(r->advice)) + "</small>";
}

// " (frozen at round 2)" for a claim an adaptive run's look decided (claim_check.h).
std::string FrozenHtml(const ClaimVerdict& v, const std::map<std::string, rounds::FrozenVerdict>& frozen) {
  auto it = frozen.find(v.claim.id);
  if (it == frozen.end()) return "";
  return " <small class=\"frozen\">(frozen at round " + std::to_string(it->second.round) + ")</small>";
}

// The first section: every claim, its verdict, the numbers behind it, the paper's, side by side.
std::string ClaimsHtml(const ReportInput& in) {
  std::string html = "<h2 id=\"claims\">Claims</h2>\n";
  if (in.claims.empty()) {
    return html + "<p class=\"none\">The campaign states no claims" +
           (in.claims_note.empty() ? std::string() : " (" + Escape(in.claims_note) + ")") + ".</p>\n";
  }
  const VerdictCounts counts = CountVerdicts(in.claims);
  html += "<p>" + std::to_string(counts.holds) + " hold, " + std::to_string(counts.differs) + " differ, " +
          std::to_string(counts.inconclusive) +
          " inconclusive, at the scale " + Escape(in.campaign_run.scale) +
          ". Each claim is decided by the rule the campaign file states (core/claims.h): a point counts only over "
          "all its replicate beds; a run cut short at the surface or the floor gives a sign and a lower bound on "
          "|U<sub>z</sub>|, not a rate; fitted laws are tested on their residuals, not on each run's few-period "
          "error; a claim never holds while a point it needs is missing, and lack of power is inconclusive. Beside "
          "each verdict, its rule's error rates at this design as the truth engine measured them (false holds, "
          "false differs: upper 95 % bounds; power: estimate and interval)." +
          (rounds::RunsInRounds(in.campaign_run)
               ? std::string(" This campaign ran in rounds: a claim decided at the look after a round is shown as it "
                             "was frozen there, never as a later look reads it; a claim still open is inconclusive "
                             "until a look decides it, whatever the runs so far read. The error rates of such a "
                             "sequence of looks are the adaptive procedure's, measured by tests/bench/bench_adaptive, "
                             "not the single-look tables' (the rounds are in the next section).")
               : std::string()) +
          (in.claims_note.empty() ? std::string() : " " + Escape(in.claims_note) + ".") +
          "</p>\n<table><tr><th>claim</th><th>verdict</th><th>measured here</th><th>the paper</th></tr>\n";
  for (const ClaimVerdict& v : in.claims) {
    std::string measured = Escape(v.reason);
    for (const ClaimPart& p : v.parts) {
      measured += "<br>" + VerdictHtml(p.verdict) + " " + Escape(p.name) + ": " + Escape(p.reason) + RatesHtml(p.rates);
      if (p.figures.empty()) continue;
      measured += "<details><summary>" + std::to_string(p.figures.size()) + " figure(s)</summary><ul>";
      for (const ClaimFigure& f : p.figures) {
        measured += "<li>" + Escape(f.name) + ": " + Escape(DescribeFigure(f)) +
                    (f.verdict ? " " + VerdictHtml(*f.verdict) : std::string()) +
                    (f.note.empty() || !(f.value || f.lo) ? std::string() : " <small>" + Escape(f.note) + "</small>") +
                    "</li>";
      }
      measured += "</ul></details>";
    }
    if (!v.missing.empty()) {
      measured += "<details><summary>" + std::to_string(v.missing.size()) +
                  " point(s) without a conclusive U<sub>z</sub></summary><ul>";
      for (const ClaimMissing& m : v.missing) {
        std::string runs;
        for (int64_t id : m.run_ids) runs += (runs.empty() ? "run " : ", ") + std::to_string(id);
        measured += "<li>" + Escape(m.sweep) + " " + Escape(DescribeClaimPoint(m.point)) + " (" + runs +
                    "): " + Escape(m.why) + "</li>";
      }
      measured += "</ul></details>";
    }
    html += "<tr id=\"claim-" + Escape(v.claim.id) + "\"><td><b>" + Escape(v.claim.id) + "</b> " +
            Escape(v.claim.title) + "<br><small>" + Escape(v.claim.source) + "; rule: " + Escape(v.claim.kind()) +
            "</small></td><td>" + VerdictHtml(v.verdict) + (v.scale.empty() ? "" : " at " + Escape(v.scale)) +
            FrozenHtml(v, in.frozen_claims) + RatesHtml(v.rates) + "</td><td>" + measured + "</td><td>" +
            PaperHtml(v.claim.paper) + "</td></tr>\n";
  }
  return html + "</table>\n";
}

// An adaptive campaign run's rounds: one row a round -- its state, what it added and why, core-h
// planned and spent, the budget left after it, each claim's state after its look -- and why they
// stopped (the same as the dashboard's table and `sandswim status cr:ID`).
std::string RoundsHtml(const ReportInput& in) {
  if (!rounds::RunsInRounds(in.campaign_run)) return "";
  auto h = [](const nlohmann::json& v) { return v.is_number() ? Num(v.get<double>(), 3) : std::string("&ndash;"); };
  if (!in.rounds_problem.empty())
    return "<h2 id=\"rounds\">Rounds</h2>\n<p class=\"none\">" + Escape(in.rounds_problem) + ".</p>\n";
  std::string html = "<h2 id=\"rounds\">Rounds</h2>\n<p>This campaign ran in rounds: a budget of " +
                     h(in.adaptive.value("budget_core_h", nlohmann::json())) + " core-h, at most " +
                     h(in.adaptive.value("max_rounds", nlohmann::json())) +
                     " rounds. After each round the daemon looked at the claims, froze each one decided, and "
                     "planned the next round for those still open. Core-hours at the cost model's rates: planned "
                     "prices each run at its maximum length, spent counts the simulated time done runs took.</p>\n";
  if (!in.rounds.is_array() || in.rounds.empty()) {
    return html +
           "<p class=\"none\">Round 1 (what was submitted) is recorded at the daemon's next scheduler tick.</p>\n";
  }
  html +=
      "<table id=\"rounds-table\"><tr><th>round</th><th>state</th><th>what it added, and why</th><th>core-h "
      "planned</th><th>core-h spent</th><th>budget left</th><th>the claims after it</th></tr>\n";
  for (const nlohmann::json& r : in.rounds) {
    const bool stopped = r.value("stop_reason", nlohmann::json()).is_string();
    const bool looked = r.value("finished_at", nlohmann::json()).is_number();
    const char* state = stopped ? "stopped" : looked ? "finished" : "running";
    std::string added;
    for (const nlohmann::json& a : r.value("actions", nlohmann::json::array()))
      added += "<li>" + Escape(a.value("reason", std::string())) + "</li>";
    std::string after = "<span class=\"none\">after its runs are done</span>";
    if (r.value("claims_after", nlohmann::json()).is_array()) {
      after.clear();
      for (const nlohmann::json& c : r["claims_after"]) {
        const std::string verdict = c.value("verdict", std::string("inconclusive"));
        after += (after.empty() ? "" : "<br>") + std::string("<span class=\"") + Escape(verdict) + "\">" +
                 Escape(c.value("claim", std::string("?"))) + " " + Escape(verdict) +
                 (c.value("frozen_at_round", nlohmann::json()).is_number()
                      ? " (frozen at round " + std::to_string(c["frozen_at_round"].get<int>()) + ")"
                      : std::string()) +
                 "</span>";
      }
    }
    html += "<tr id=\"round-" + std::to_string(r.value("round", 0)) + "\"><td>" + std::to_string(r.value("round", 0)) +
            "</td><td>" + state + "</td><td>" + (added.empty() ? "nothing" : "<ul>" + added + "</ul>") + "</td><td>" +
            h(r.value("core_h_planned", nlohmann::json())) + "</td><td>" +
            h(r.value("core_h_spent", nlohmann::json())) +
            "</td><td>" + h(r.value("budget_left_core_h", nlohmann::json())) + "</td><td>" + after + "</td></tr>\n";
  }
  html += "</table>\n";
  const nlohmann::json& last = in.rounds.back();
  if (last.value("stop_reason", nlohmann::json()).is_string()) {
    html += "<p id=\"rounds-stop\"><b>Stopped after round " + std::to_string(last.value("round", 0)) + ":</b> " +
            Escape(last["stop_reason"].get<std::string>()) + "</p>\n";
  } else {
    html += "<p id=\"rounds-stop\" class=\"none\">Round " + std::to_string(last.value("round", 0)) +
            " runs; the daemon looks at the claims once its runs are done.</p>\n";
  }
  return html;
}

}  // namespace

// ---- HTML --------------------------------------------------------------------------------------

std::string RenderReportHtml(const ReportInput& in) {
  const CampaignRunInfo& cr = in.campaign_run;
  const std::string title =
      "sandswim report: " + cr.campaign + " at " + cr.scale + ", campaign run cr:" + std::to_string(cr.id);
  std::string html =
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" + Escape(title) +
      "</title>\n<style>\n"
      "body{font-family:sans-serif;margin:2em;max-width:1100px}table{border-collapse:collapse;margin:1em 0}"
      "td,th{border:1px solid #bbb;padding:3px 8px;text-align:left;vertical-align:top}"
      "figure{margin:1em 0}figure svg{width:100%;height:auto}figcaption{color:#555}"
      ".none{color:#777}.drifted{background:#fdd}details{margin:0.5em 0}"
      ".problems{background:#fdd;padding:0.2em "
      "1em}.holds{background:#dfd}.differs{background:#fdd}.inconclusive{background:#eee}\n"
      "</style>\n</head>\n<body>\n<h1 id=\"top\">" +
      Escape(title) + "</h1>\n<p>Generated " + UtcTime(in.generated_at) + ". Created " + UtcTime(cr.created_at) + " (" +
      Escape(cr.trigger) + "). Runs: " + std::to_string(cr.counts.done) + " done, " + std::to_string(cr.counts.queued) +
      " queued, " + std::to_string(cr.counts.running) + " running, " + std::to_string(cr.counts.failed) + " failed, " +
      std::to_string(cr.counts.cancelled) + " cancelled.</p>\n";

  if (!in.problems.empty()) {
    html += "<div class=\"problems\"><p>" + std::to_string(in.problems.size()) +
            " part(s) of this report could not be made; each says so where it would be. Ask for the report "
            "again once the cause is fixed (see the daemon's log):</p><ul>";
    for (const std::string& p : in.problems) html += "<li>" + Escape(p) + "</li>";
    html += "</ul></div>\n";
  }
  html += ClaimsHtml(in);
  html += RoundsHtml(in);
  html += "<nav><h2>Contents</h2><ul>\n<li><a href=\"#claims\">Claims</a></li>\n";
  if (rounds::RunsInRounds(in.campaign_run)) html += "<li><a href=\"#rounds\">Rounds</a></li>\n";
  if (!in.modes_z_svg.empty()) html += "<li><a href=\"#modes\">Drive modes side by side</a></li>\n";
  if (!in.snapshots.empty()) html += "<li><a href=\"#bed\">The bed: slices through the SO</a></li>\n";
  html += "<li><a href=\"#fits\">Fits</a></li>\n";
  for (const ReportSweep& s : in.sweeps) {
    html += "<li><a href=\"#sweep-" + std::to_string(s.info.id) + "\">sweep " + std::to_string(s.info.id) + ": " +
            Escape(s.info.name) + "</a></li>\n";
  }
  html += "<li><a href=\"#drift\">Drift report</a></li>\n</ul></nav>\n";

  if (!in.modes_z_svg.empty()) {
    html +=
        "<h2 id=\"modes\">Drive modes side by side</h2>\n<p>Each drive other than the oscillatory one, as in the "
        "paper's Fig. 2: the SO's horizontal (x) and vertical (z) displacement from its start. "
        "<a href=\"#top\">top</a></p>\n";
    html += FigureHtml(in.modes_x_svg, "fig-modes-x", "Δx(t) of each drive mode");
    html += FigureHtml(in.modes_z_svg, "fig-modes-z", "Δz(t) of each drive mode");
  }

  if (!in.snapshots.empty()) {
    html +=
        "<h2 id=\"bed\">The bed: slices through the SO</h2>\n<p>As in the paper's Fig. 5: the whole bed at the "
        "times its runs asked for, cut by the plane x = x<sub>SO</sub>. Each grain the plane cuts is a disc of its "
        "cut radius, coloured by its speed; the SO is outlined. Each snapshot is also served whole, as a VTK file "
        "ParaView opens (<code>GET /api/v1/runs/ID/snapshots/N.vtk</code>). <a href=\"#top\">top</a></p>\n";
    for (const ReportSnapshot& snap : in.snapshots) {
      const std::string id = "run-" + std::to_string(snap.run_id) + "-snapshot-" + std::to_string(snap.meta.idx);
      html += FigureHtml(snap.slice_svg, "fig-" + id,
                         "run " + std::to_string(snap.run_id) + " (" + snap.label + "), t = " + Num(snap.meta.t_s, 3) +
                             " s (" + Num(snap.meta.fraction, 3) + " of the run), " +
                             std::to_string(snap.meta.grains) + " grains: snapshots/" +
                             std::to_string(snap.meta.idx) + ".vtk");
    }
  }

  html +=
      "<h2 id=\"fits\">Fits</h2>\n<p>Least squares; ± is one standard error. \"paper's sign\": rising for "
      "Ω &lt; 0, sinking for Ω &gt; 0.</p>\n<table><tr><th>sweep (branch)</th><th>law</th><th>parameters</th>"
      "<th>R²</th><th>over</th><th>paper's sign</th><th>runs</th></tr>\n";
  for (const ReportSweep& s : in.sweeps) html += FitRows(s);
  html += "</table>\n";

  for (const ReportSweep& s : in.sweeps) {
    const std::string id = std::to_string(s.info.id);
    html += "<section id=\"sweep-" + id + "\">\n<h2>sweep " + id + ": " + Escape(s.info.name) + "</h2>\n<p>" +
            Escape(s.fits.choice.reason) + ". <a href=\"#top\">top</a></p>\n";
    for (const auto& [branch, svg] : s.trajectories_svg) {
      html += FigureHtml(svg, "fig-sweep-" + id + "-trajectories" + (branch.empty() ? "" : "-" + branch),
                         branch.empty() ? "Δz(t) of every finished run of sweep " + id
                                        : "Δz(t) of the " + branch + " branch of sweep " + id + " (" +
                                              std::string(OmegaSide(ParseBranch(branch).value_or(Branch::kSinking))) +
                                              ")");
    }
    html += FigureHtml(s.uz_svg, "fig-sweep-" + id + "-uz",
                       "U_z of sweep " + id + " against " +
                           (s.fits.choice.param.empty() ? std::string("its point") : s.fits.choice.param) +
                           ", with the fitted law",
                       s.no_uz);
    html +=
        "<table><tr><th>run</th><th>point</th><th>state</th><th>U<sub>z</sub> (m/s, ± standard error, "
        "whole periods)</th><th>Δz/T (m/s, whole run)</th><th>window ends</th></tr>\n";
    for (const ReportRun& r : s.runs) {
      html += "<tr><td><a href=\"#run-" + std::to_string(r.run_id) + "\">" + std::to_string(r.run_id) +
              "</a></td><td>" + Escape(r.label) + "</td><td>" + Escape(ToString(r.state)) + "</td><td" +
              (r.inconclusive_reason.empty() ? std::string(">") : " title=\"" + Escape(r.inconclusive_reason) + "\">") +
              (r.uz_text.empty() ? std::string("–") : Escape(r.uz_text)) + "</td><td>" +
              (r.dz_rate ? Num(*r.dz_rate, 2) : std::string("–")) + "</td><td>" + Escape(r.window_end) + "</td></tr>\n";
    }
    html += "</table>\n";
    for (const ReportRun& r : s.runs) {
      if (!r.anchored) continue;
      html += "<details id=\"run-" + std::to_string(r.run_id) + "\"><summary>run " + std::to_string(r.run_id) + ": " +
              Escape(r.label) + "</summary>\n" +
              FigureHtml(r.trajectory_svg, "fig-run-" + std::to_string(r.run_id),
                         "Δz(t) and Δx(t) of run " + std::to_string(r.run_id)) +
              "</details>\n";
    }
    html += "</section>\n";
  }
  html += "<h2 id=\"drift\">Drift report</h2>\n" + DriftHtml(in.drift) + "<p><a href=\"#top\">top</a></p>\n";
  return html + "</body>\n</html>\n";
}

Result<std::string> CampaignReport(Store& store, FigureCache& figures, int64_t campaign_run_id, double now,
                                   const std::string& data_dir) {
  auto cr = store.GetCampaignRun(campaign_run_id);
  if (!cr.ok()) return cr.status();
  ReportInput in;
  in.campaign_run = *cr;
  in.generated_at = now;
  auto drift = DriftReportFor(store, campaign_run_id);
  if (!drift.ok()) return drift.status();
  in.drift = *drift;
  auto analyzed = AnalyzeCampaignRun(store, *cr);
  if (!analyzed.ok()) return analyzed.status();
  const std::vector<SweepAnalysis>& analyses = *analyzed;
  // A claim check or a figure that fails costs its part of the report, never the report: it is
  // said where the part would be, and listed at the top.
  auto claims = CheckClaims(store, *cr, analyses);
  if (claims.ok()) {
    in.claims = std::move(claims->verdicts);
    in.claims_note = claims->note;
    in.frozen_claims = std::move(claims->frozen);
  } else {
    in.claims_note = "the claims could not be checked: " + claims.status().ToString();
    in.problems.push_back(in.claims_note);
  }
  // The rounds' read failing costs their section, like the claims' (RoundsHtml says so there).
  in.adaptive = rounds::AdaptiveSettingsJson(*cr);
  if (rounds::RunsInRounds(*cr)) {
    auto rounds = rounds::RoundsReply(store, *cr);
    if (rounds.ok()) {
      in.rounds = (*rounds)["rounds"];
    } else {
      in.rounds_problem = "the rounds could not be read: " + rounds.status().ToString();
      in.problems.push_back(in.rounds_problem);
    }
  }
  auto draw = [&](const std::string& name, const Plot& plot) -> std::string {
    auto svg = figures.Get(name, plot, ImageFormat::kSvg);
    if (svg.ok()) return *svg;
    in.problems.push_back("figure " + name + " could not be drawn: " + svg.status().ToString());
    return NotDrawnSvg(svg.status().ToString());
  };
  for (Coordinate c : {Coordinate::kX, Coordinate::kZ}) {
    std::optional<Plot> modes = ModesFigure(*cr, analyses, c);
    if (!modes) break;
    (c == Coordinate::kX ? in.modes_x_svg : in.modes_z_svg) = draw(ModesFigureName(cr->id, c), *modes);
  }
  if (!data_dir.empty()) {
    std::set<int64_t> seen;
    for (const SweepAnalysis& a : analyses) {
      for (const RunTrajectory& t : a.runs) {
        if (!seen.insert(t.run_id).second) continue;
        auto run = store.GetRun(t.run_id, Store::Deck::kLeftOut);
        if (!run.ok()) return run.status();
        for (const api::Snapshot& meta : run->snapshots) {
          ReportSnapshot snap{t.run_id, PointLabel(t.point, ""), meta, ""};
          const std::string name = "run-" + std::to_string(t.run_id) + "-snapshot-" + std::to_string(meta.idx) + "-slice";
          auto bed = ReadStoredSnapshot(data_dir, t.run_id, meta.idx);
          if (bed.ok()) {
            snap.slice_svg = draw(name, SnapshotSlicePlot(t.run_id, t.point, meta, SliceThroughSo(*bed)));
          } else {
            in.problems.push_back("figure " + name + " could not be drawn: " + bed.status().ToString());
            snap.slice_svg = NotDrawnSvg(bed.status().ToString());
          }
          in.snapshots.push_back(std::move(snap));
        }
      }
    }
  }
  // A run shared by several sweeps is drawn once and shown (anchored) under its first sweep only,
  // so every "#run-ID" names exactly one element.
  std::set<int64_t> shown;
  for (const SweepAnalysis& analysis : analyses) {
    const int64_t sweep_id = analysis.info.id;
    const SweepAnalysis* a = &analysis;
    ReportSweep s;
    s.info = a->info;
    s.fits = a->fits;
    for (const std::string& branch : TrajectoryBranches(*a)) {
      Plot plot = SweepTrajectoriesFigure(*a, branch);
      std::string svg_text;
      if (!plot.series.empty()) svg_text = draw(SweepTrajectoriesName(sweep_id, branch), plot);
      s.trajectories_svg.emplace_back(branch, std::move(svg_text));
    }
    s.no_uz = NoUzToPlot(*a);
    if (s.no_uz.empty()) s.uz_svg = draw(SweepUzName(sweep_id), SweepUzFigure(*a));
    auto rows = store.SweepResults(sweep_id);
    if (!rows.ok()) return rows.status();
    for (const ResultRow& row : *rows) {
      ReportRun r;
      r.anchored = shown.insert(row.run_id).second;
      r.run_id = row.run_id;
      r.label = PointLabel(row.point, "");
      r.state = row.state;
      if (row.result) {
        r.uz_text = DescribeUz(row.result->result, false);
        r.dz_rate = row.result->result.dz_rate;
        r.window_end = row.result->result.window_end;
        r.inconclusive_reason = row.result->result.inconclusive_reason;
      }
      for (const RunTrajectory& t : a->runs) {
        if (t.run_id != row.run_id || !r.anchored) continue;
        r.trajectory_svg = draw(RunFigureName(t.run_id), RunTrajectoryPlot(t.run_id, t.point, t.trajectory,
                                                                           row.result ? &row.result->result : nullptr));
      }
      s.runs.push_back(std::move(r));
    }
    in.sweeps.push_back(std::move(s));
  }
  return RenderReportHtml(in);
}

}  // namespace sandswim
