# The model in the loop (Hasler et al. 2009 register their scans with their own model once it
# exists; docs/real-registration.md#the-model-in-the-loop):
#   round 1: register-mesh the meshes with the population prior (MakeHuman's macro sliders, or
#            `shape_space`, a file of `bodymodel shape-space`), writing each registration carried
#            back to the rest pose (--rest);
#   model:   build a model of those rest-pose registrations TOGETHER WITH population bodies
#            (synth-db --truth-only, e.g. ANSUR II soldiers; docs/population.md);
#   round r: register the same meshes again with `--model` = round r−1's model, build again;
#   correspondence after every round when `truth` is given (eval-correspondence).
# Resumable: Snakemake remakes only missing outputs, and register-mesh skips the meshes a round
# already finished. The model of round r contains the registrations of the meshes round r+1
# registers again (as in Hasler's loop): a measure of self-consistency, not of unseen people.
#
# Run (config keys below; paths absolute or relative to the working folder):
#   snakemake -s workflow/bootstrap.smk --cores 1 --config bodymodel=build/bodymodel out=loop \
#     meshes=meshes.txt landmarks=registration/landmarks/faust.json scale=1000 \
#     population=$A/ansur2_female.csv,$A/ansur2_male.csv truth=$BODYMODEL_DATA/faust-registrations
import os
import re

BODYMODEL = config.get("bodymodel", "bodymodel")
OUT = config.get("out", "bootstrap")
ROUNDS = int(config.get("rounds", 2))
# The meshes: a text file listing them (whitespace-separated), or a list in a --configfile.
_meshes = config["meshes"]
MESHES = _meshes if isinstance(_meshes, list) else open(_meshes).read().split()
LANDMARKS = config["landmarks"]
SCALE = config.get("scale", 1)
REGISTER_ARGS = config.get("register_args", "--jobs 1")
SHAPE_SPACE = config.get("shape_space", "")               # round 1's prior (empty: macro sliders)
MODEL_ARGS = config.get("model_args", "")                 # e.g. "--model-components 30 --model-prior 1"
# Population bodies: a synth-db --truth-only folder (population_db), or made here from `population`.
POPULATION = config.get("population", "")
POPULATION_DB = config.get("population_db", os.path.join(OUT, "population"))
POPULATION_ARGS = config.get("population_args", "--subjects 60 --seed 1 --jobs 1")
BUILD_ARGS = config.get("build_args", "--no-measure --no-rig --components 40")
TRUTH = config.get("truth", "")
CORRESPONDENCE_ARGS = config.get(
    "correspondence_args", "--truth-scale 1000 --subject-regex 'tr_reg_(\\d\\d)\\d'")

if ROUNDS < 1:
    raise ValueError("rounds must be at least 1")
if not MESHES:
    raise ValueError("meshes: no meshes listed")
STEMS = [os.path.splitext(os.path.basename(m))[0] for m in MESHES]
if len(set(STEMS)) != len(STEMS):
    raise ValueError("meshes: two meshes share a file name")


def round_dir(r):
    return os.path.join(OUT, f"round{r}")


targets = [os.path.join(round_dir(r), "model.npz") for r in range(1, ROUNDS + 1)]
if TRUTH:
    targets += [os.path.join(round_dir(r), "correspondence", "summary.csv") for r in range(1, ROUNDS + 1)]


rule all:
    input:
        targets,


if not os.path.exists(os.path.join(POPULATION_DB, "scans.csv")):

    rule population:
        output:
            os.path.join(POPULATION_DB, "scans.csv"),
        log:
            os.path.join(OUT, "logs", "population.log"),
        run:
            if not POPULATION:
                raise ValueError("population: give `population` (synth-db --population FILES) or `population_db`")
            shell("{BODYMODEL} synth-db --population {POPULATION} --poses-per-subject 0 --truth-only "
                  "{POPULATION_ARGS} --out {POPULATION_DB} > {log} 2>&1")


# Round r's registrations (exit 2 = some meshes failed: listed in the log, left out of the model).
rule register:
    input:
        lambda w: [] if int(w.r) == 1 else [os.path.join(round_dir(int(w.r) - 1), "model.npz")],
    output:
        os.path.join(OUT, "round{r}", "reg", "register-mesh.csv"),
    log:
        os.path.join(OUT, "logs", "register{r}.log"),
    run:
        prior = f"--model {input[0]} {MODEL_ARGS}" if int(wildcards.r) > 1 else (
            f"--shape-space {SHAPE_SPACE}" if SHAPE_SPACE else "")
        reg = os.path.dirname(output[0])
        shell("{BODYMODEL} register-mesh {MESHES} --landmarks {LANDMARKS} --scale {SCALE} --rest {prior} "
              "{REGISTER_ARGS} --out {reg} > {log} 2>&1 || [ $? -eq 2 ]")


# The training set of round r's model: every rest-pose registration and every population body,
# each its own subject (a shape sample), linked into one folder with build's subjects table.
rule training_set:
    input:
        os.path.join(OUT, "round{r}", "reg", "register-mesh.csv"),
        os.path.join(POPULATION_DB, "scans.csv"),
    output:
        os.path.join(OUT, "round{r}", "train", "subjects.csv"),
    run:
        train = os.path.dirname(output[0])
        os.makedirs(train, exist_ok=True)
        reg = os.path.dirname(input[0])
        rows = []
        for stem in STEMS:
            src = os.path.join(reg, stem + ".rest.ply")
            if os.path.exists(src):
                rows.append((stem, src))
        for line in open(input[1]).read().splitlines()[1:]:
            scan_id = line.split(",")[0]
            rows.append(("population_" + scan_id, os.path.join(POPULATION_DB, "truth", scan_id + ".ply")))
        with open(output[0] + ".tmp", "w") as f:
            f.write("mesh,subject,pose\n")
            for name, src in rows:
                link = os.path.join(train, name + ".ply")
                if os.path.lexists(link):
                    os.remove(link)
                os.symlink(os.path.abspath(src), link)
                f.write(f"{name},{name},rest\n")
        os.replace(output[0] + ".tmp", output[0])


rule build:
    input:
        os.path.join(OUT, "round{r}", "train", "subjects.csv"),
    output:
        os.path.join(OUT, "round{r}", "model.npz"),
    log:
        os.path.join(OUT, "logs", "build{r}.log"),
    run:
        train = os.path.dirname(input[0])
        shell("{BODYMODEL} build {train} --subjects {input[0]} --standard-pose rest {BUILD_ARGS} "
              "--out {output[0]} > {log} 2>&1")


rule correspondence:
    input:
        os.path.join(OUT, "round{r}", "reg", "register-mesh.csv"),
    output:
        os.path.join(OUT, "round{r}", "correspondence", "summary.csv"),
    log:
        os.path.join(OUT, "logs", "correspondence{r}.log"),
    run:
        reg = os.path.dirname(input[0])
        dest = os.path.dirname(output[0])
        shell("{BODYMODEL} eval-correspondence {reg} --truth {TRUTH} --landmarks {LANDMARKS} --out {dest} "
              "{CORRESPONDENCE_ARGS} > {log} 2>&1")
