#include "skinning/method_comparison.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "core/error.h"

namespace bodymodel {

namespace {

std::string explicit_protocol(const FrameSplitRequest& r, int nf) {
  const int distinct = int(std::set<int>(r.train.begin(), r.train.end()).size());
  return r.explicit_test
             ? fmt::format("explicit split: {} training frames (--train), {} unseen (--test)", r.train.size(),
                           nf - int(r.train.size()))
             : fmt::format("{} training frames listed with --train, the other {} unseen", r.train.size(), nf - distinct);
}

}  // namespace

FrameSplit split_frames(int nf, const FrameSplitRequest& r) {
  if (nf < 2) throw InputError(fmt::format("skin eval: {} frame(s); a comparison needs at least 2", nf));
  if (r.rest >= nf) throw InputError(fmt::format("skin eval: rest frame {} of {} frames", r.rest, nf));
  FrameSplit s;
  s.rest = r.rest;
  if (r.leave_one_out) {
    if (s.rest < 0) s.rest = 0;
    for (int f = 0; f < nf; ++f) {
      if (f == s.rest) continue;  // the rest frame is always a training frame
      std::vector<int> t;
      for (int g = 0; g < nf; ++g)
        if (g != f) t.push_back(g);
      s.folds.push_back(t);
    }
    s.protocol = fmt::format("leave-one-out over {} frames (rest frame {} always trained)", nf,
                             size_t(s.rest) < r.frame_names.size() ? r.frame_names[size_t(s.rest)] : std::to_string(s.rest));
    return s;
  }
  std::vector<int> t;
  if (!r.train.empty()) {
    for (int f : r.train)
      if (f < 0 || f >= nf) throw InputError(fmt::format("skin eval: training frame {} of {} frames", f, nf));
    t = r.train;
    s.protocol = explicit_protocol(r, nf);
  } else if (r.train_fraction > 0) {
    if (!(r.train_fraction < 1)) throw InputError("--train-fraction must be in (0, 1)");
    const int k = std::max(1, int(std::lround(r.train_fraction * nf)));
    for (int f = 0; f < k; ++f) t.push_back(f);
    s.protocol = fmt::format("the first {} of {} frames trained ({:g} %), the rest unseen", k, nf, 100 * r.train_fraction);
  } else if (r.train_every > 0) {
    for (int f = 0; f < nf; f += r.train_every) t.push_back(f);
    s.protocol = fmt::format("every {}th frame trained", r.train_every);
  } else {
    const int k = r.train_count > 0 ? r.train_count : std::max(1, std::min(10, nf - 1));
    t = evenly_spaced_frames(nf, k);
    s.protocol = fmt::format("{} evenly spaced training frames", t.size());
  }
  const std::set<int> tset(t.begin(), t.end());
  if (int(tset.size()) >= nf)
    throw InputError(fmt::format("skin eval: the training frames ({}) are all {} frames of the sequence, leaving "
                                 "no unseen frame to measure (train on at most {})",
                                 s.protocol, nf, nf - 1));
  if (s.rest < 0) s.rest = *tset.begin();
  const int last_train = *tset.rbegin();
  s.forecast = !r.explicit_test;
  for (int f = 0; f < nf; ++f)
    if (!tset.count(f) && f < last_train) s.forecast = false;
  s.folds.push_back(t);
  return s;
}

SkinCrossValidationOptions parse_cv_scheme(const std::string& s, bool forecast) {
  SkinCrossValidationOptions o;
  const auto bad = [&] { return InputError("--cv: expected auto, none, folds:K or last:N, found '" + s + "'"); };
  auto number = [&](const std::string& v) {
    try {
      size_t used = 0;
      const int n = std::stoi(v, &used);
      if (used != v.size() || n < 0) throw bad();
      return n;
    } catch (const std::exception&) {
      throw bad();
    }
  };
  if (s == "none") {
    o.scheme = CvScheme::none;
  } else if (s == "auto") {
    o.scheme = forecast ? CvScheme::last : CvScheme::interleaved;
  } else if (s.rfind("folds:", 0) == 0) {
    o.scheme = CvScheme::interleaved;
    o.folds = number(s.substr(6));
  } else if (s.rfind("last:", 0) == 0) {
    o.scheme = CvScheme::last;
    o.held_out = number(s.substr(5));
  } else {
    throw bad();
  }
  return o;
}

std::string cv_description(const SkinCrossValidationOptions& o) {
  if (o.scheme == CvScheme::none) return "none (settings as given)";
  const std::string rule = fmt::format(", rule {}, nesting {}", cv_rule_name(o.rule), cv_nesting_name(o.nesting));
  if (o.scheme == CvScheme::interleaved)
    return fmt::format("{}-fold interleaved over the training frames{}", o.folds, rule);
  return (o.held_out > 0 ? fmt::format("the last {} training frames held back", o.held_out)
                         : std::string("the last third of the training frames held back")) +
         rule;
}

namespace {

// The candidates of one method's cross-validation, with the rules that would keep each (only the
// rule in force shaped the fitted models; the others can be read off without a rerun).
void add_cv_rows(SkinningComparison& c, size_t fold, const MethodFit& fit) {
  std::vector<CvCandidate> cands = fit.cv.candidates;
  std::vector<std::string> by(cands.size());
  if (!cands.empty())
    for (CvRule r : {CvRule::minimum, CvRule::one_se, CvRule::one_se_unpaired}) {
      std::string& b = by[select_candidate(cands, r)];
      b += (b.empty() ? "" : " ") + cv_rule_name(r);
    }
  for (size_t k = 0; k < cands.size(); ++k)
    c.cv_rows.push_back({fold, fit.method, cands[k], cands[k].setting == fit.cv.chosen_setting, by[k]});
}

}  // namespace

void check_comparison(int frame_count, const FrameSplit& split, SequenceEvaluationOptions options) {
  options.rest_frame = split.rest;
  for (const auto& fold : split.folds) check_evaluation_request(frame_count, fold, options);
}

SkinningComparison compare_skinning_methods(const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F,
                                            const FrameSplit& split, SequenceEvaluationOptions opt,
                                            const ProgressCallback& progress) {
  const int nf = int(frames.size());
  check_comparison(nf, split, opt);
  opt.rest_frame = split.rest;
  const size_t M = opt.methods.size(), folds = split.folds.size();
  SkinningComparison c;
  c.methods = opt.methods;
  c.train.resize(M);
  c.unseen.resize(M);
  c.per_vertex_unseen.assign(M, Eigen::VectorXd::Zero(frames[0].rows()));
  c.frame_error.assign(M, std::vector<double>(size_t(nf), 0.0));
  c.frame_split.assign(size_t(nf), "train");
  c.fit_cpu.assign(M, 0.0);
  for (size_t fold = 0; fold < folds; ++fold) {
    const ProgressCallback sub = [&](double f, std::string_view w) {
      return !progress || progress((double(fold) + f) / double(folds), w);
    };
    c.last = evaluate_skinning_sequence(frames, F, split.folds[fold], opt, {}, sub);
    c.seconds += c.last.seconds;
    c.prepare_cpu += c.last.prepare_cpu_seconds;
    c.cv_setup_cpu += c.last.cv_setup_cpu_seconds;
    for (const auto& row : c.last.rows) {
      const size_t m = size_t(std::find(opt.methods.begin(), opt.methods.end(), row.method) - opt.methods.begin());
      (row.split == "train" ? c.train[m] : c.unseen[m]).merge(row.stats);
    }
    const std::set<int> tset(split.folds[fold].begin(), split.folds[fold].end());
    for (size_t m = 0; m < M; ++m) {
      c.fit_cpu[m] += c.last.fits[m].cpu_seconds;
      add_cv_rows(c, fold, c.last.fits[m]);
      c.per_vertex_unseen[m] += c.last.mean_unseen_geometric[m] / double(folds);
      for (int f = 0; f < nf; ++f)
        if (!tset.count(f) || folds == 1) c.frame_error[m][size_t(f)] = c.last.frame_mean_geometric[m][size_t(f)];
    }
    for (int f = 0; f < nf; ++f)
      if (!tset.count(f)) c.frame_split[size_t(f)] = "unseen";
  }
  return c;
}

}  // namespace bodymodel
