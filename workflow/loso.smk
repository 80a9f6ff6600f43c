# Leave one subject out (docs/model.md §5.7): for every person of a folder of registrations, a
# model is built from the other people's registrations together with population bodies
# (synth-db --truth-only, e.g. ANSUR II soldiers; docs/population.md) and fitted (`eval-model`,
# the fit of model/fit.h) to the left-out person's registrations, beside a vertex PCA of the same
# training meshes. One fold per job: each fold writes its folder (quality.csv, generalisation.csv)
# when it ends and deletes its model, so an interrupted run resumes at the first missing fold.
# summary.csv pools the folds (mean over every test mesh) and lists each fold.
#
# Run (paths absolute or relative to the working folder):
#   snakemake -s workflow/loso.smk --cores 1 --config bodymodel=build/bodymodel out=loso \
#     registrations=REG population_db=pop60 population_count=60
# Keys (defaults below): registrations = a folder of NAME.ply (one topology, mm), NAME's subject
# the first group of subject_regex (FAUST: tr_reg_([0-9][0-9])[0-9]; write [0-9], not a
# backslash: Snakemake hands --config values on to the jobs it runs and loses the backslash);
# population_count = 0 is the control without population bodies; population (synth-db
# --population FILES) makes population_db here.
import os
import re

BODYMODEL = config.get("bodymodel", "bodymodel")
OUT = config.get("out", "loso")
REGISTRATIONS = config["registrations"]
SUBJECT_REGEX = config.get("subject_regex", "tr_reg_([0-9][0-9])[0-9]")
POPULATION = config.get("population", "")
POPULATION_DB = config.get("population_db", os.path.join(OUT, "population"))
POPULATION_COUNT = int(config.get("population_count", 0))
POPULATION_ARGS = config.get("population_args", "--seed 1 --jobs 1")
BUILD_ARGS = config.get("build_args", "--full-variance 1 --no-rig --no-measure")
# K: every component of each fold's model unless `components` names one count.
COMPONENTS = int(config.get("components", 0))
EVAL_ARGS = config.get("eval_args", "--samples 0")
KEEP_MODELS = str(config.get("keep_models", False)).lower() in ("1", "true", "yes")

# The registrations and their subjects; a pose name per mesh (p0, p1, … in name order per
# subject), p0 being the subject's standard pose for build's shape model.
_names = sorted(os.path.splitext(f)[0] for f in os.listdir(REGISTRATIONS) if f.endswith(".ply")
                and not f.endswith(".rest.ply"))
SUBJECT = {}
for n in _names:
    m = re.fullmatch(SUBJECT_REGEX, n)
    if m:
        SUBJECT[n] = m.group(1)
SUBJECTS = sorted(set(SUBJECT.values()))
if len(SUBJECTS) < 2:
    raise ValueError(f"registrations: {len(SUBJECTS)} subject(s) match subject_regex in {REGISTRATIONS}")
POSE = {}
for s in SUBJECTS:
    for i, n in enumerate(n for n in SUBJECT if SUBJECT[n] == s):
        POSE[n] = f"p{i}"


def fold_dir(s):
    return os.path.join(OUT, f"fold_{s}")


rule all:
    input:
        os.path.join(OUT, "summary.csv"),


if POPULATION_COUNT > 0 and not os.path.exists(os.path.join(POPULATION_DB, "scans.csv")):

    rule population:
        output:
            os.path.join(POPULATION_DB, "scans.csv"),
        log:
            os.path.join(OUT, "logs", "population.log"),
        run:
            if not POPULATION:
                raise ValueError("population_count > 0: give `population` (synth-db --population FILES) or `population_db`")
            shell("{BODYMODEL} synth-db --population {POPULATION} --poses-per-subject 0 --truth-only "
                  "--subjects {POPULATION_COUNT} {POPULATION_ARGS} --out {POPULATION_DB} > {log} 2>&1")


def population_ids():
    if POPULATION_COUNT <= 0:
        return []
    rows = open(os.path.join(POPULATION_DB, "scans.csv")).read().splitlines()[1:]
    ids = [r.split(",")[0] for r in rows if r]
    if len(ids) < POPULATION_COUNT:
        raise ValueError(f"population_db {POPULATION_DB} has {len(ids)} bodies, population_count is {POPULATION_COUNT}")
    return ids[:POPULATION_COUNT]


# One fold: the training folder (links), build, eval-model on the left-out subject's meshes.
rule fold:
    input:
        [os.path.join(POPULATION_DB, "scans.csv")] if POPULATION_COUNT > 0 else [],
    output:
        quality=os.path.join(OUT, "fold_{s}", "q", "quality.csv"),
        per_mesh=os.path.join(OUT, "fold_{s}", "q", "generalisation.csv"),
    log:
        build=os.path.join(OUT, "logs", "build_{s}.log"),
        evaluation=os.path.join(OUT, "logs", "eval_{s}.log"),
    run:
        d = fold_dir(wildcards.s)
        train = os.path.join(d, "train")
        os.makedirs(train, exist_ok=True)
        rows, test = [], []
        for n, s in SUBJECT.items():
            if s == wildcards.s:
                test.append(f"{n},{s},{POSE[n]}")
                continue
            rows.append((n, os.path.join(REGISTRATIONS, n + ".ply"), f"{n},{s},{POSE[n]}"))
        for i in population_ids():
            rows.append(("population_" + i, os.path.join(POPULATION_DB, "truth", i + ".ply"),
                         f"population_{i},population_{i},rest"))
        for name, src, _ in rows:
            link = os.path.join(train, name + ".ply")
            if os.path.lexists(link):
                os.remove(link)
            os.symlink(os.path.abspath(src), link)
        for path, lines in ((os.path.join(d, "train.csv"), [r[2] for r in rows]), (os.path.join(d, "test.csv"), test)):
            with open(path, "w") as f:
                f.write("mesh,subject,pose\n" + "".join(line + "\n" for line in lines))
        model = os.path.join(d, "model.npz")
        shell("{BODYMODEL} build {train} --subjects {d}/train.csv --standard-pose p0 {BUILD_ARGS} "
              "--out {model} > {log.build} 2>&1")
        k = COMPONENTS
        if k <= 0:  # every component: the count build printed ("full model: N meshes, K components")
            m = re.search(r"full model:\s+\d+ meshes, (\d+) components", open(log.build).read())
            if not m:
                raise ValueError(f"{log.build}: no component count of the full model")
            k = int(m.group(1))
        q = os.path.dirname(output.quality)
        shell("{BODYMODEL} eval-model {model} --test {REGISTRATIONS} --test-subjects {d}/test.csv --train {train} "
              "--components {k} {EVAL_ARGS} --out {q} --force > {log.evaluation} 2>&1")
        if not KEEP_MODELS:
            os.remove(model)


# Every fold's rows and the pooled means (over all test meshes of all folds; a p95 pooled over
# folds' vertices needs the vertices, so only each fold's p95 is listed).
rule summary:
    input:
        per_mesh=[os.path.join(OUT, f"fold_{s}", "q", "generalisation.csv") for s in SUBJECTS],
        quality=[os.path.join(OUT, f"fold_{s}", "q", "quality.csv") for s in SUBJECTS],
    output:
        os.path.join(OUT, "summary.csv"),
    run:
        import csv
        lines = ["fold,model,components,test_meshes,mean_mm,p95_mm,unconverged_fits"]
        pooled = {}
        for s, path in zip(SUBJECTS, input.per_mesh):
            q = {r["model"]: r for r in csv.DictReader(open(os.path.join(os.path.dirname(path), "quality.csv")))}
            per = list(csv.DictReader(open(path)))
            for model, r in q.items():
                means = [float(p["mean_mm"]) for p in per if p["model"] == model]
                unconverged = sum(p["converged"] == "0" for p in per if p["model"] == model)
                lines.append(f"{s},{model},{r['components']},{len(means)},{float(r['generalisation_mean_mm']):.3f},"
                             f"{float(r['generalisation_p95_mm']):.3f},{unconverged if model == 'rre' else ''}")
                acc = pooled.setdefault(model, [[], 0])
                acc[0] += means
                acc[1] += unconverged
        for model, (means, unconverged) in pooled.items():
            lines.append(f"all,{model},,{len(means)},{sum(means) / len(means):.3f},,"
                         f"{unconverged if model == 'rre' else ''}")
        with open(output[0] + ".tmp", "w") as f:
            f.write("\n".join(lines) + "\n")
        os.replace(output[0] + ".tmp", output[0])
