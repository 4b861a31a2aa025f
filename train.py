"""Train SportsNGEN (decoder f and event classifier g): `python train.py experiment=tiny`.

Configs in conf/ (groups data, model, trainer, callbacks, logger, experiment); see
`sportsngen.train.run`.
"""

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from sportsngen.train.run import train_from_config


@hydra.main(version_base=None, config_path="conf", config_name="train")
def main(cfg: DictConfig) -> None:
    train_from_config(cfg, HydraConfig.get().runtime.output_dir)


if __name__ == "__main__":
    main()
