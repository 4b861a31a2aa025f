"""Studies: train or simulate variants of a model, score them, write a markdown table.

`variants` freezes a data set, trains a variant from Hydra overrides and caches its result;
`tables` writes the markdown. One module a study (`heads`, `ablations`, `finetune`, `top_p`,
`horizon`, `outcome`, `evaluation_report`, `ceiling`); each `scripts/<study>.py` parses its
arguments and calls that module's entry point.
"""
