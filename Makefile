# Deployment helpers. `make bundle` builds dist/edge-vis.pyz (see deploy/build-bundle.sh).
.PHONY: bundle clean-bundle

bundle:
	bash deploy/build-bundle.sh

clean-bundle:
	rm -rf dist/edge-vis.pyz build/wheelhouse
