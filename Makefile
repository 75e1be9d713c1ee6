# reflcheck - build, test, benchmark and report.
#   make            library, CLI and tests          make test     unit + renderer tests
#   make report     the nightly report (all renderers, large renders)
#   make bench      rasterizer benchmarks            make fuzz     coverage-guided fuzzing
#   make check T=NAME   one unit-test program (tests/test_NAME.c)
#   make install    PREFIX=/usr/local DESTDIR=: program, manual page, bash completion, run-time data
#   SANITIZE=1      AddressSanitizer + UBSan build   DEBUG=1       -O0 -g3
CC ?= cc
CXX ?= c++
PKGS := OpenEXR yaml-0.1 cmocka libcjson libpng libjpeg nlopt assimp

WARN    := -Wall -Wextra -Wpedantic -Wshadow -Wstrict-prototypes -Wmissing-prototypes \
           -Wpointer-arith -Wcast-qual -Wvla -Wformat=2
# Messages are cut to their buffers on purpose (snprintf); a cut path is still readable.
WARN    += -Wno-format-truncation
STD     := -std=c11 -D_POSIX_C_SOURCE=200809L
OPT     := $(if $(DEBUG),-O0 -g3,-O2 -g)
# The shading kernels' lane loops are `#pragma omp simd` (render/shade_batch_*.c): the pragma only,
# no OpenMP runtime.
OPT     += -fopenmp-simd
# Value-safe (no reassociation, no FMA contraction in ISO C): math functions need not set errno
# and operations may run when their result is discarded, so branches in lane loops become selects.
OPT     += -fno-math-errno -fno-trapping-math
SANFLAGS := -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=all
SAN     := $(if $(SANITIZE),$(SANFLAGS))
DEPFLAGS = -MMD -MP
# The layers, bottom to top (ARCHITECTURE.md; tests/layers.py fails on an include that points up):
# every header is found by its name alone, so a file's layer is its folder.
LAYERS    := core model scene render harness cli
LAYER_INC := $(LAYERS:%=-I%)
CFLAGS  ?=
CFLAGS  += $(STD) $(OPT) $(WARN) $(SAN) -pthread $(LAYER_INC) $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
LDLIBS  += $(SAN) -pthread $(shell pkg-config --libs $(PKGS) 2>/dev/null) -ldl -lm
# One C++ file, scene/image_oiio.cpp, is a C shim over OpenImageIO's C++ API (DDS files), built
# as a plugin with the two model files it uses: linked into the programs, OpenImageIO's 263
# libraries made every process start take 0.77 s (scene/image_dds.c loads it at first use).
OIIO_PKG := OpenImageIO
CXXFLAGS ?=
CXXFLAGS += -std=c++17 $(OPT) -Wall -Wextra -Wpedantic -Wshadow -Wformat=2 -Wno-format-truncation $(SAN) -pthread \
            -fPIC $(LAYER_INC) $(shell pkg-config --cflags $(OIIO_PKG) 2>/dev/null)

BUILD ?= build$(if $(SANITIZE),-san)$(if $(DEBUG),-dbg)

# The project version, defined here once; `reflcheck --version` and the manual page add the git
# commit the program was built from ("-dirty" when the tree differs from it). A tree without
# git: make REFLCHECK_COMMIT=<id>.
VERSION := 0.9.0
ifndef REFLCHECK_COMMIT
REFLCHECK_COMMIT := $(shell c=$$(git rev-parse --short=12 HEAD 2>/dev/null) && { git diff --quiet HEAD -- 2>/dev/null || c=$$c-dirty; }; echo $${c:-unknown})
endif
VERSION_DEFS := -DREFLCHECK_VERSION='"$(VERSION)"' -DREFLCHECK_COMMIT='"$(REFLCHECK_COMMIT)"'
# Rewritten (while make reads this file) only when the version or commit changed, so the objects
# that print them are rebuilt then and a second `make all` stays a no-op.
VERSION_STAMP := $(BUILD)/version.stamp
ifeq ($(filter clean,$(MAKECMDGOALS)),)
$(shell mkdir -p $(BUILD) && { [ "$$(cat $(VERSION_STAMP) 2>/dev/null)" = "$(VERSION) $(REFLCHECK_COMMIT)" ] || echo "$(VERSION) $(REFLCHECK_COMMIT)" > $(VERSION_STAMP); })
endif

# The library: every layer's C files but the program's main. Each renderer is a folder under
# harness/renderers/ (registry.c holds the table).
LIB_SRC     := $(filter-out cli/main.c,$(wildcard $(LAYERS:%=%/*.c) harness/renderers/*.c harness/renderers/*/*.c))
TEST_SRC    := $(wildcard tests/test_*.c)
LIB_OBJ     := $(LIB_SRC:%.c=$(BUILD)/%.o)
TEST_BIN    := $(TEST_SRC:tests/%.c=$(BUILD)/tests/%)
LIBS        := $(BUILD)/libreflcheck.a
CLI         := $(BUILD)/reflcheck
OIIO_PLUGIN := $(BUILD)/reflcheck-oiio.so
OIIO_PLUGIN_OBJ := $(BUILD)/pic/scene/image_oiio.o $(BUILD)/pic/core/fileio.o $(BUILD)/pic/core/status.o
KEY_SOURCES := $(BUILD)/key-sources/.stamp
# The manual page and the bash completion, written from the command table (tools/gen_man.c).
GEN_MAN     := $(BUILD)/tools/gen_man
CLI_DOCS    := $(BUILD)/reflcheck.1 $(BUILD)/reflcheck.bash
# Users' shading models built as shared objects (rules below): the example and the test fixtures.
USER_FIXTURES := no_entry abi_2 nan bad_bounds null_eval
USER_MODELS := $(BUILD)/examples/ggx/ggx.so $(USER_FIXTURES:%=$(BUILD)/tests/user_models/%.so)

.PHONY: all check test test-unit test-scenes test-mutant test-kill test-status test-concurrent test-report test-fuzz test-renderer \
        test-slurm test-install test-layers bench report nightly-build fuzz fuzz-assimp deps clean install
all: $(CLI) $(TEST_BIN) $(KEY_SOURCES) $(CLI_DOCS) $(USER_MODELS)

deps:
	@bash ops/deps.sh

$(BUILD)/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) $(DEPFLAGS) -c $< -o $@
$(BUILD)/pic/%.o: %.cpp
	@mkdir -p $(dir $@)
	$(CXX) $(CXXFLAGS) $(DEPFLAGS) -c $< -o $@
$(BUILD)/pic/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -fPIC $(DEPFLAGS) -c $< -o $@
$(OIIO_PLUGIN): $(OIIO_PLUGIN_OBJ)
	$(CXX) -shared $(SAN) -pthread $^ $(shell pkg-config --libs $(OIIO_PKG) 2>/dev/null) -o $@
# The plugin's path, fixed at build time (REFLCHECK_OIIO_PLUGIN overrides it when the program runs).
$(BUILD)/scene/image_dds.o: CFLAGS += -DREFLCHECK_OIIO_PLUGIN='"$(abspath $(OIIO_PLUGIN))"'
# The tree whose scripts Blender runs, so reflcheck works from any folder (REFLCHECK_DATA_DIR
# overrides it when the program runs).
$(BUILD)/harness/renderers/renderer.o: CFLAGS += -DREFLCHECK_DATA_DIR='"$(abspath .)"'
# Each renderer's cache-key sources from the build's own objects and .d files, never a hand list
# (harness/renderers/key_sources.py); jobs.c reads them from here (REFLCHECK_KEY_SOURCES overrides).
$(KEY_SOURCES): $(LIB_OBJ) $(OIIO_PLUGIN_OBJ) harness/renderers/key_sources.py
	python3 harness/renderers/key_sources.py $(BUILD) $(LIB_OBJ) && touch $@
$(BUILD)/harness/jobs.o: CFLAGS += -DREFLCHECK_KEY_SOURCES='"$(abspath $(BUILD))/key-sources"'

# Users' shading models (model/user_model.h, docs/user_models.md): the shipped example and the
# loader tests' broken models (tests/user_model_fixture.c, one -D per way of being wrong). Each is
# a shared object on its own, built from model/user_model.h alone, as a user builds theirs.
USER_CFLAGS := -std=c11 -O2 -fPIC -shared $(WARN) -Imodel
$(BUILD)/examples/ggx/ggx.so: examples/ggx/ggx.c model/user_model.h
	@mkdir -p $(dir $@)
	$(CC) $(USER_CFLAGS) $< -lm -o $@
$(BUILD)/tests/user_models/%.so: tests/user_model_fixture.c model/user_model.h
	@mkdir -p $(dir $@)
	$(CC) $(USER_CFLAGS) -DFIXTURE_$(shell echo $* | tr a-z A-Z) $< -o $@
$(BUILD)/tests/test_user_model: | $(USER_MODELS)
$(BUILD)/tests/test_user_model.o: CFLAGS += -DUSER_MODELS_DIR='"$(abspath $(BUILD))"'

$(BUILD)/libreflcheck.a: $(LIB_OBJ)
	rm -f $@ && $(AR) rcs $@ $^

$(CLI): $(BUILD)/cli/main.o $(LIBS) | $(OIIO_PLUGIN) $(KEY_SOURCES)
	$(CC) $(CFLAGS) $(filter-out $(OIIO_PLUGIN),$^) $(LDLIBS) -o $@

$(BUILD)/cli/main.o $(BUILD)/tools/gen_man.o: $(VERSION_STAMP)
$(BUILD)/cli/main.o $(BUILD)/tools/gen_man.o: CFLAGS += $(VERSION_DEFS)
$(GEN_MAN): $(BUILD)/tools/gen_man.o $(LIBS)
	$(CC) $(CFLAGS) $^ $(LDLIBS) -o $@
$(BUILD)/reflcheck.1: $(GEN_MAN)
	$(GEN_MAN) man > $@.tmp && mv $@.tmp $@
$(BUILD)/reflcheck.bash: $(GEN_MAN)
	$(GEN_MAN) bash > $@.tmp && mv $@.tmp $@

# make install [PREFIX=/usr/local] [DESTDIR=]: the program, its DDS plugin, the manual page, the
# bash completion, and the files it reads at run time (the scripts Blender runs, the key-source
# lists and the sources they name, so cache keys match the tree's) under PREFIX/share/reflcheck.
# The installed program is linked with its own copies of the three objects that name where those
# are (renderer.c, image_dds.c, jobs.c), compiled with PREFIX paths, so it runs from anywhere
# without the source tree or the build folder; DESTDIR only stages the files.
PREFIX  ?= /usr/local
DESTDIR ?=
INST_DIR  := $(BUILD)/install
INST_DATA := $(PREFIX)/share/reflcheck
INST_LIB  := $(PREFIX)/lib/reflcheck
INST_OBJ  := $(INST_DIR)/harness/renderers/renderer.o $(INST_DIR)/scene/image_dds.o $(INST_DIR)/harness/jobs.o
INST_DEFS := -DREFLCHECK_DATA_DIR='"$(INST_DATA)"' -DREFLCHECK_KEY_SOURCES='"$(INST_DATA)/key-sources"' \
             -DREFLCHECK_OIIO_PLUGIN='"$(INST_LIB)/reflcheck-oiio.so"'
ifneq ($(filter install,$(MAKECMDGOALS)),)
$(shell mkdir -p $(INST_DIR) && { [ "$$(cat $(INST_DIR)/prefix.stamp 2>/dev/null)" = "$(PREFIX)" ] || echo "$(PREFIX)" > $(INST_DIR)/prefix.stamp; })
endif
$(INST_DIR)/%.o: %.c $(INST_DIR)/prefix.stamp
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) $(INST_DEFS) $(DEPFLAGS) -c $< -o $@
$(INST_DIR)/reflcheck: $(BUILD)/cli/main.o $(INST_OBJ) $(LIBS)
	$(CC) $(CFLAGS) $^ $(LDLIBS) -o $@
install: $(INST_DIR)/reflcheck $(OIIO_PLUGIN) $(CLI_DOCS) $(KEY_SOURCES)
	install -d "$(DESTDIR)$(PREFIX)/bin" "$(DESTDIR)$(INST_LIB)" "$(DESTDIR)$(PREFIX)/share/man/man1" \
	    "$(DESTDIR)$(PREFIX)/share/bash-completion/completions" "$(DESTDIR)$(INST_DATA)/key-sources"
	install -m 755 $(INST_DIR)/reflcheck "$(DESTDIR)$(PREFIX)/bin/reflcheck"
	install -m 755 $(OIIO_PLUGIN) "$(DESTDIR)$(INST_LIB)/reflcheck-oiio.so"
	install -m 644 $(BUILD)/reflcheck.1 "$(DESTDIR)$(PREFIX)/share/man/man1/reflcheck.1"
	install -m 644 $(BUILD)/reflcheck.bash "$(DESTDIR)$(PREFIX)/share/bash-completion/completions/reflcheck"
	install -m 644 $(BUILD)/key-sources/*.list "$(DESTDIR)$(INST_DATA)/key-sources/"
	{ cat $(BUILD)/key-sources/*.list; ls harness/renderers/*/*.py; } | sort -u | while read -r f; do \
	    install -D -m 644 "$$f" "$(DESTDIR)$(INST_DATA)/$$f" || exit 1; done

$(BUILD)/tests/%: $(BUILD)/tests/%.o $(LIBS) | $(OIIO_PLUGIN)
	$(CC) $(CFLAGS) $(filter-out $(OIIO_PLUGIN),$^) $(LDLIBS) -o $@
# The test objects are made by a pattern chain, so make would delete them as intermediates after
# each build and compile all of them again on the next `make all` (a second `make report` was
# never a no-op). Kept, they are up to date like every other object.
.SECONDARY: $(TEST_BIN:=.o)

# make install into a scratch prefix: the files, the manual page as groff renders it, the
# completion, and the installed program rendering POV-Ray and Cycles jobs from another folder.
test-install: all
	@bash tests/install.sh $(BUILD)

# The layering (ARCHITECTURE.md): no include points from a layer to one above it.
test-layers:
	@python3 tests/layers.py

# Unit tests (also the sanitizer run in CI), then the renderer-backed tests.
test-unit: $(TEST_BIN) $(CLI)
	@bash tests/run_unit.sh $(BUILD)

# One unit-test program alone: `make check T=jobs` runs tests/test_jobs.c's program.
check: $(CLI)
	@test -n "$(T)" || { echo "usage: make check T=NAME (a tests/test_NAME.c program)"; exit 2; }
	$(MAKE) $(BUILD)/tests/test_$(T)
	REFLCHECK_BIN=$(CLI) $(BUILD)/tests/test_$(T)

# Builds use every CPU; the test steps themselves run one after another (they share ports,
# a Slurm cluster and folders), each parallel inside where it can be.
NPROC := $(shell nproc 2>/dev/null || echo 2)
test: deps
	$(MAKE) -j$(NPROC) all
	@$(MAKE) -q all || { echo "make test: a second 'make all' would rebuild (intermediates deleted?)"; exit 1; }
	$(MAKE) test-layers
	$(MAKE) -j$(NPROC) SANITIZE=1 test-unit
	$(MAKE) test-unit
	$(MAKE) test-scenes
	$(MAKE) test-mutant test-kill test-status test-concurrent test-report test-fuzz test-renderer test-slurm test-install

# A model broken on purpose (Fresnel exponent p + 1) fails exactly the scenes that use it.
test-mutant: $(CLI)
	@bash tests/mutant_fresnel.sh $(BUILD)

# Killing the nightly run at random points loses no history record and leaves no process.
test-kill: $(CLI)
	@bash tests/kill_nightly.sh $(BUILD)

# The nightly's exit status and recorded run status: ok, a failing comparison, a crashing renderer;
# its progress lines, a failed job named while the run goes on, its options and their variables;
# a second run over the same cache takes the fits and the stability table from it; `make report`
# builds only what the nightly runs and checks the packages with one dpkg-query.
test-status: $(CLI)
	@bash tests/nightly_build.sh $(BUILD)
	@bash tests/nightly_status.sh $(BUILD)
	@bash tests/nightly_paths.sh $(BUILD)
	@bash tests/nightly_progress.sh $(BUILD)
	@bash tests/nightly_cache.sh $(BUILD)

# Two nightlies at once on one cache: both complete, the shared jobs render once, and both
# history lines are intact.
test-concurrent: $(CLI)
	@bash tests/concurrent_nightly.sh $(BUILD)

# Adding a renderer is a folder and one row of harness/renderers/registry.c: done in a scratch
# copy, built, and checked through the CLI, a plan, a job and deps.sh.
test-renderer:
	@bash tests/add_renderer.sh $(BUILD)

# The fuzzers, briefly, so that their build and a first pass over the corpus run in every CI.
test-fuzz:
	$(MAKE) -j$(NPROC) fuzz FUZZ_TIME=$(TEST_FUZZ_TIME)
TEST_FUZZ_TIME ?= 15

# The nightly through a one-node Slurm cluster it starts and stops itself: the same verdicts,
# metrics and images as with make, every job a Slurm job; failed and cancelled jobs recorded.
# Then on two nodes, and with one of them killed mid-run: jobs on both, the lost one requeued,
# the same verdicts as on one node. Then a Blender worker's images against a fresh Blender's,
# for Cycles and for EEVEE (under the pool's own Xvfb).
test-slurm: $(CLI)
	@bash tests/slurm_nightly.sh $(BUILD)
	@bash tests/slurm_nodes.sh $(BUILD)
	@bash tests/slurm_worker.sh $(BUILD)
	@bash tests/eevee_worker.sh $(BUILD)

# The report generator, the report opened in headless Chromium, the gates table (tools/gates.py:
# every gate beside its figure, none loose without a stated reason) and the cost table
# (tools/cost_table.py) on a run folder the test makes; the fits' expected costs (ops/fit_costs.py).
test-report: $(CLI)
	@REFLCHECK_BIN=$(CLI) /usr/bin/python3 -m pytest -q -p no:cacheprovider tests/test_report.py tests/test_sweep.py tests/test_progress.py tests/test_answer.py tests/test_gates_table.py \
		tests/test_cost_table.py tests/test_fit_costs.py

# Every canonical scene, small, in the real POV-Ray and Blender, gated on its thresholds; first
# the crease rules of harness/crease.h shown by a ridge quad in the same renderers (seconds),
# and where the error sits on two known-answer scenes against exact (angle bins, seconds), and
# image.samples auto's refusals and its count from a pilot in Cycles (seconds), and Cycles
# shading with our float normals, not Blender's 16-bit copy (mirror_sphere's twin, seconds), and
# a job's seeds in one Cycles session, each its own seed, and a cube map's importance map (~20 s).
test-scenes: $(CLI)
	@bash tests/crease_renderers.sh $(BUILD)
	@bash tests/angle_bins.sh $(BUILD)
	@bash tests/cycles_auto.sh $(BUILD)
	@bash tests/cycles_normals.sh $(BUILD)
	@bash tests/cycles_setup.sh $(BUILD)
	@bash tests/run_scenes.sh $(BUILD)

# The nightly report: full-size renders in all renderers, metrics, plots, history.
# SCHEDULER=slurm: the renders, the sweep and compare as Slurm jobs (docs/slurm.md).
# Your own scenes: make report SCENES="my/a.yaml my/b.yaml" ARGS="--small --no-sweep" (ARGS: the
# options of bash ops/nightly.sh --help); the run goes to reports/runs/, which git ignores.
# The nightly builds only what it runs: the program, its DDS plugin, the cache-key lists and the
# example shading model scenes/user_ggx.yaml loads; not the 50 unit-test programs, their fixtures
# or the manual page, which `make all` adds (a third of a clean build's CPU time).
SCHEDULER ?= make
# The SIMD shading kernels are most of the library's compiling (three ISA clones of every lane
# loop, all inlined), one file per model family so that they compile side by side; named first,
# longest first (CPU-s: shade_batch_ct 36-41, shade_batch_d3d9 21-22.5, shade_batch_d3d 3.5-3.8),
# make -j starts them at once and the other files fill the cores. On an idle 2-core machine the
# build takes half its CPU, 42 s, where the one file it was took 65 s (docs/render_time.md).
SB_KERNEL_OBJ := $(BUILD)/render/shade_batch_ct.o $(BUILD)/render/shade_batch_d3d9.o $(BUILD)/render/shade_batch_d3d.o
NIGHTLY_FIRST := $(foreach o,$(SB_KERNEL_OBJ),$(filter $(o),$(LIB_OBJ)))
# Their line tables are enough (backtraces, profiles): full debug information of three clones of
# every lane kernel cost 9.5 of the single file's 34.7 CPU-s, for the same machine code.
$(SB_KERNEL_OBJ): CFLAGS += $(if $(DEBUG),,-g1)
NIGHTLY_BUILD := $(CLI) $(OIIO_PLUGIN) $(KEY_SOURCES) $(BUILD)/examples/ggx/ggx.so
nightly-build: $(NIGHTLY_FIRST) $(NIGHTLY_BUILD)
report: deps
	$(MAKE) -j$(NPROC) nightly-build
	@SCHEDULER=$(SCHEDULER) BIN="$${BIN:-$(CLI)}" bash ops/nightly.sh $(ARGS)

# Coverage-guided fuzzing (libFuzzer) of the scene parser and the EXR reader; findings go
# to tests/regress/ once fixed. FUZZ_TIME seconds per target. The fuzz targets link the whole
# library, built once with the fuzzer's instrumentation, so a new dependency between our own
# files can never break their link again.
FUZZ_CC    ?= clang
FUZZ_TIME  ?= 300
FUZZ_CFLAGS := -g -O1 -fopenmp-simd -Wno-pass-failed -fsanitize=address,undefined -fno-sanitize-recover=all \
               $(STD) $(LAYER_INC) $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
FUZZ_DIR   := $(abspath $(BUILD))/fuzz
FUZZ_OBJ   := $(LIB_SRC:%.c=$(FUZZ_DIR)/obj/%.o)

$(FUZZ_DIR)/obj/%.o: %.c
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -fsanitize=fuzzer-no-link $(DEPFLAGS) -c $< -o $@
$(FUZZ_DIR)/libreflcheck_fuzz.a: $(FUZZ_OBJ)
	rm -f $@ && $(AR) rcs $@ $^
$(FUZZ_DIR)/fuzz_%: tests/fuzz/fuzz_%.c $(FUZZ_DIR)/libreflcheck_fuzz.a
	$(FUZZ_CC) $(FUZZ_CFLAGS) -fsanitize=fuzzer $^ -pthread $(shell pkg-config --libs $(PKGS) 2>/dev/null) -ldl -lm -o $@

fuzz: deps $(FUZZ_DIR)/fuzz_scene $(FUZZ_DIR)/fuzz_exr $(FUZZ_DIR)/fuzz_texture
	@mkdir -p $(FUZZ_DIR)/corpus_scene $(FUZZ_DIR)/corpus_exr $(FUZZ_DIR)/corpus_texture $(FUZZ_DIR)/artifacts
	cd scenes && $(FUZZ_DIR)/fuzz_scene -max_total_time=$(FUZZ_TIME) -print_final_stats=1 \
	    -artifact_prefix=$(FUZZ_DIR)/artifacts/scene- $(FUZZ_DIR)/corpus_scene ../tests/fuzz/corpus/scene
	$(FUZZ_DIR)/fuzz_exr -max_total_time=$(FUZZ_TIME) -print_final_stats=1 \
	    -artifact_prefix=$(FUZZ_DIR)/artifacts/exr- $(FUZZ_DIR)/corpus_exr tests/fuzz/corpus/exr
	$(FUZZ_DIR)/fuzz_texture -max_total_time=$(FUZZ_TIME) -print_final_stats=1 \
	    -artifact_prefix=$(FUZZ_DIR)/artifacts/texture- $(FUZZ_DIR)/corpus_texture tests/fuzz/corpus/texture
# Assets through libassimp (tests/fuzz/fuzz_assimp.c), on its own and not in `make fuzz` (so not
# in test-fuzz): it imports in its own process, so libassimp's own crashes (docs/assets.md: one
# found in minutes) stop it, where reflcheck's child process turns them into a refusal. The seeds
# are assimp-testmodels' small single-file assets (.x, .stl, .off), where the package installs
# them. Leak checks are off: libassimp 5.2.5 leaks inside its importers on some inputs (4.9 kB in
# the seed corpus, no frame of ours). An allocation over 1 GiB fails (bad_alloc, which libassimp
# reports as a refusal) instead of stopping the fuzzer: one input asked for 25 GB, as reflcheck's
# child meets its RLIMIT_DATA.
FUZZ_ASSIMP_SEEDS := $(wildcard /usr/share/assimp/models/X /usr/share/assimp/models/OFF /usr/share/assimp/models/STL)
fuzz-assimp: $(FUZZ_DIR)/fuzz_assimp
	@mkdir -p $(FUZZ_DIR)/corpus_assimp $(FUZZ_DIR)/artifacts
	ASAN_OPTIONS=allocator_may_return_null=1:max_allocation_size_mb=1024:detect_leaks=0 \
	$(FUZZ_DIR)/fuzz_assimp -max_total_time=$(FUZZ_TIME) -print_final_stats=1 -max_len=65536 -detect_leaks=0 \
	    -malloc_limit_mb=0 -rss_limit_mb=4096 \
	    -artifact_prefix=$(FUZZ_DIR)/artifacts/assimp- $(FUZZ_DIR)/corpus_assimp $(FUZZ_ASSIMP_SEEDS)
-include $(FUZZ_OBJ:.o=.d)

# Benchmarks: the rasterizer across sizes, threads and triangle counts, llvmpipe (OSMesa) on
# the same frame, POV-Ray and Cycles beside them. Targets live here, never in timed tests.
BENCH_SRC := $(wildcard tests/bench/*.c)
BENCH_BIN := $(BUILD)/bench/bench_raster $(BUILD)/bench/bench_llvmpipe
$(BUILD)/tests/bench/%.o: CFLAGS += -Itests/bench $(shell pkg-config --cflags osmesa 2>/dev/null)
$(BUILD)/bench/bench_raster: $(BUILD)/tests/bench/bench_raster.o $(BUILD)/tests/bench/bench_scene.o $(LIBS)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) $^ $(LDLIBS) -o $@
$(BUILD)/bench/bench_llvmpipe: $(BUILD)/tests/bench/bench_llvmpipe.o $(BUILD)/tests/bench/bench_scene.o $(LIBS)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) $^ $(LDLIBS) $(shell pkg-config --libs osmesa 2>/dev/null) -o $@
bench: deps
	$(MAKE) $(CLI) $(BENCH_BIN)
	@bash tests/bench/run.sh $(BUILD)
-include $(BENCH_SRC:%.c=$(BUILD)/%.d)

clean:
	rm -rf build build-san build-dbg build-san-dbg

-include $(LIB_OBJ:.o=.d) $(TEST_BIN:=.d) $(BUILD)/cli/main.d $(OIIO_PLUGIN_OBJ:.o=.d) \
         $(BUILD)/tools/gen_man.d $(INST_OBJ:.o=.d)
