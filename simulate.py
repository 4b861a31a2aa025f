"""Simulate tennis matches: `python simulate.py [player1=... player2=... engine=... seed=...]`.

Thin Hydra entry point; the work is in `sportsngen.cli.simulate`.
"""

import hydra
from omegaconf import DictConfig


@hydra.main(version_base=None, config_path="conf", config_name="simulate")
def main(cfg: DictConfig) -> None:
    from sportsngen.cli.simulate import run_simulation

    run_simulation(cfg)


if __name__ == "__main__":
    main()
