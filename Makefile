# odocal: `make demo` runs the whole synthetic experiment, `make test` the tests.
# Both first install the Debian packages the build needs (idempotent).

SHELL := /bin/bash
APT_PACKAGES := libopencv-dev libblas3 liblapack3 clang libclang-dev pkg-config chromium ffmpeg
CARGO ?= cargo
DEMO_OUT ?= demo-out

.PHONY: deps build demo demo-arena test lint bench clean

deps:
	@./scripts/install-deps.sh $(APT_PACKAGES)
	@./scripts/select-blas.sh

build: deps
	$(CARGO) build --release

# The build is timed too: the demo's summary reports it with the stages.
demo: deps
	@start=$$(date +%s); $(CARGO) build --release && \
	  DEMO_BUILD_S=$$(( $$(date +%s) - start )) ./scripts/demo.sh $(DEMO_OUT)

# Four ceiling cameras over a 6 x 4 m floor, two robots: calibrate each camera, tie them into
# one floor frame, track both robots across the four videos, compare with the truth, report.
ARENA_OUT ?= $(DEMO_OUT)/arena
demo-arena: deps
	$(CARGO) build --release
	rm -rf $(ARENA_OUT)
	target/release/odocal synth arena --out $(ARENA_OUT)
	for k in 0 1 2 3; do target/release/odocal calibrate $(ARENA_OUT)/cam$$k/view_*.png \
	  --floor $(ARENA_OUT)/cam$$k/floor_*.png --board 9x6 --square 0.07 \
	  --out $(ARENA_OUT)/cam$$k/camera.json | tail -n 2 || exit 1; done
	target/release/odocal arena --camera $(ARENA_OUT)/cam{0,1,2,3}/camera.json \
	  --shared $(ARENA_OUT)/shared --out $(ARENA_OUT)/arena.json
	target/release/odocal track --arena $(ARENA_OUT)/arena.json $(ARENA_OUT)/video_c{0,1,2,3} \
	  --tags 0,3 --tag-size 0.16 --out $(ARENA_OUT)/robot.csv \
	  --arena-report $(ARENA_OUT)/arena-track.json --arena-truth $(ARENA_OUT)
	target/release/odocal report --arena $(ARENA_OUT)/arena.json \
	  --arena-track $(ARENA_OUT)/arena-track.json --out $(ARENA_OUT)/report.html

test: deps
	$(CARGO) test --workspace --no-fail-fast

lint: deps
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --workspace --all-targets -- -D warnings

bench: deps
	$(CARGO) bench

clean:
	$(CARGO) clean
	rm -rf $(DEMO_OUT)
