# bevy_aslod: `make demo` runs the main demo, `make test` runs every test.
# Both install what they need first (Debian/Ubuntu packages, as root or through sudo).

APT_PACKAGES := pkg-config libwayland-dev libxkbcommon-dev libasound2-dev libudev-dev \
                libx11-dev mesa-vulkan-drivers xvfb xauth
TESTDATA     := ../shared/testdata
CARGO        ?= cargo

.PHONY: demo silvretta test check-deps deps lint bench bench-bevy bench-render bench-instances bench-instance-cost soak figure-11 compare

deps:
	@missing=$$(for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
		echo "installing:$$missing"; \
		SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
		$$SUDO apt-get update -qq && \
		DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing; \
	fi

# The aerobic class (ASLOD Figures 9-11): three dancing mannequins under 5,000 triangles, in a
# window when there is a display, otherwise rendered offscreen through lavapipe into
# out/aerobic_class (frames.csv, frame_time.png, allocation.png, screenshots, summary.json).
demo: deps
	@if [ -n "$$DISPLAY$$WAYLAND_DISPLAY" ]; then \
		$(CARGO) run --features ui --example aerobic_class; \
	else \
		echo "no display: rendering headless into out/aerobic_class"; \
		$(CARGO) run --features ui --example aerobic_class -- --headless --frames 120 --report out/aerobic_class && \
		cat out/aerobic_class/summary.json; \
	fi

# The Silvretta terrain (ASLOD Figure 8), the same way, into out/silvretta.
silvretta: deps
	@if [ -n "$$DISPLAY$$WAYLAND_DISPLAY" ]; then \
		$(CARGO) run --features ui --example silvretta; \
	else \
		echo "no display: rendering headless into out/silvretta"; \
		$(CARGO) run --features ui --example silvretta -- --headless --frames 10 --screenshot out/silvretta && \
		cat out/silvretta/counts.json; \
	fi

# Three passes, so that Bevy is compiled, and linked into a binary, only where a test needs it:
# everything without Bevy (the core, the CLI, the core benches run once each); the two Bevy
# test binaries (the plugin headless, and the render tests, which build and run the examples)
# and the Bevy benches, built only; then the doctests.
test: deps check-deps
	$(CARGO) test --no-default-features --features cli --lib --bins --tests --benches
	$(CARGO) test --all-features --lib --test plugin --test render
	$(CARGO) test --all-features --no-run --bench plugin --bench skinned_crowd
	$(CARGO) test --all-features --doc

# What `cargo add bevy_aslod` pulls: Bevy, glam, gltf, thiserror and log (and bytemuck, half and
# bevy_mikktspace, which Bevy has anyway, and crc32fast, which gltf's PNG decoder has), so no
# meshopt (a C++ build), clap or indicatif: those are the `cli` feature's.
DEFAULT_DEPS := bevy bevy_mikktspace bytemuck crc32fast glam gltf half log thiserror
# The Bevy features the plugin asks for (Cargo.toml; bevy_gltf for `gltf_instancing`): no
# windowing, input, UI or audio.
BEVY_FEATURES := async_executor bevy_asset bevy_core_pipeline bevy_gizmos bevy_gltf bevy_log bevy_pbr bevy_render multi_threaded std
check-deps:
	@direct=$$($(CARGO) tree -e normal --depth 1 --prefix none --format '{p}' | sed 1d | cut -d' ' -f1 | sort -u | tr '\n' ' '); \
	if [ "$$direct" != "$(DEFAULT_DEPS) " ]; then \
		echo "the default build's dependencies are [$$direct], expected [$(DEFAULT_DEPS)]"; exit 1; fi; \
	if $(CARGO) tree -e normal --prefix none --format '{p}' | grep -q '^meshopt'; then \
		echo "the default build compiles meshopt (C++)"; exit 1; fi; \
	echo "default dependencies: $$direct"; \
	features=$$($(CARGO) tree -e normal,features -i bevy --prefix none --format '{p}' | sed -n 's/^bevy feature "\(.*\)".*/\1/p' | sort -u | tr '\n' ' '); \
	if [ "$$features" != "$(BEVY_FEATURES) " ]; then \
		echo "the default build asks Bevy for [$$features], expected [$(BEVY_FEATURES)]"; exit 1; fi; \
	if $(CARGO) tree -e normal --prefix none --format '{p}' | grep -qE '^(winit|gilrs|x11|wayland|bevy_ui|bevy_text|bevy_picking|bevy_audio) '; then \
		echo "the default build pulls windowing, input, UI or audio"; exit 1; fi; \
	echo "Bevy features: $$features"

lint:
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --all-features --all-targets -- -D warnings
	$(CARGO) clippy --no-default-features --lib --tests -- -D warnings

bench:
	$(CARGO) bench --no-default-features --bench multires --bench budget --bench skin --bench frame_core

# The Bevy benches (release builds of Bevy take long on small machines).
bench-bevy: deps
	$(CARGO) bench --bench plugin --bench skinned_crowd

# What a level change costs the renderer, with rendering on (lavapipe without a GPU): the
# 1,000-model scene, Silvretta and the aerobic class (docs/performance.md).
bench-render: deps
	$(CARGO) build --release --example render_cost
	@for s in grid silvretta aerobic; do \
		$(CARGO) run --release --quiet --example render_cost -- --scene $$s --frames 60; done

# The long session: 10,000 frames of spawning, despawning and budget changes, headless, then
# drawn through Vulkan (lavapipe without a GPU). One at a time: each judges the process's
# resident memory.
soak:
	ASLOD_SOAK_FRAMES=10000 $(CARGO) test --all-features --test plugin soak -- --nocapture --test-threads=1

# The instance bench: shared levels against meshoptimizer levels under VisibilityRange
# (release: our code and Bevy's at the same optimisation).
bench-instances: deps
	xvfb-run -a $(CARGO) run --release --example render_cost -- --instances 1000,10000 --crowd 100 --frames 30

# The per-instance CPU cost without a renderer: the plugin against Bevy's frustum culling.
bench-instance-cost:
	$(CARGO) run --release --example instance_cost -- --counts 1000,10000,100000 --frames 30
	$(CARGO) run --release --example instance_cost -- --dancers 20,200 --frames 30

# ASLOD Figure 11 measured (docs/performance.md): the aerobic class at 960x540 (lavapipe is
# bound by pixels there) and 240x135 (by geometry), 5 interleaved runs each, and the
# 100-dancer crowd at 240x135, into out/figure_11. On a GPU, scripts/gpu_figure_11.sh alone
# runs the paper's 1920x1080.
figure-11: deps
	SIZES=960x540,240x135 CROWD_SIZES=240x135 CARGO=$(CARGO) scripts/gpu_figure_11.sh out/figure_11

# The command-line tool without Bevy: a release Bevy build would take long.
compare:
	@for m in stanford-bunny cow fandisk spot; do \
		$(CARGO) run --release --quiet --no-default-features --features cli --bin aslod -- \
			compare $(TESTDATA)/meshes/$$m.obj --regions clusters:16; done
