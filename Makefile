# bevy_aslod: `make demo` runs the main demo, `make test` runs every test.
# Both install what they need first (Debian/Ubuntu packages, as root or through sudo).

APT_PACKAGES := pkg-config libwayland-dev libxkbcommon-dev libasound2-dev libudev-dev \
                libx11-dev mesa-vulkan-drivers xvfb
TESTDATA     := ../shared/testdata
CARGO        ?= cargo

.PHONY: demo test deps lint bench compare

deps:
	@missing=$$(for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
		echo "installing:$$missing"; \
		SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
		$$SUDO apt-get update -qq && \
		DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing; \
	fi

# The Silvretta terrain (ASLOD Figure 8): in a window when there is a display, otherwise
# rendered offscreen through lavapipe into out/silvretta (PNGs and per-region counts).
demo: deps
	@if [ -n "$$DISPLAY$$WAYLAND_DISPLAY" ]; then \
		$(CARGO) run --example silvretta; \
	else \
		echo "no display: rendering headless into out/silvretta"; \
		xvfb-run -a $(CARGO) run --example silvretta -- --headless --frames 10 --screenshot out/silvretta && \
		cat out/silvretta/counts.json; \
	fi

test: deps
	$(CARGO) test --no-default-features --lib --tests
	$(CARGO) test --all-targets
	$(CARGO) test --doc

lint:
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --all-targets -- -D warnings
	$(CARGO) clippy --no-default-features --lib --tests -- -D warnings

bench:
	$(CARGO) bench --no-default-features --bench multires --bench budget

compare:
	@for m in stanford-bunny cow fandisk spot; do \
		$(CARGO) run --release --quiet --bin aslod -- compare $(TESTDATA)/meshes/$$m.obj; done
