"""Measuring deblurring and scene flow: metrics, the benchmarks behind the paper's tables.

A library (nothing here imports the command line); each benchmark has one typed entry
point returning a frozen dataclass:

- :func:`.planar_bench.run_planar_bench`: Table 2 on rendered planes;
- :func:`.sceneflow_bench.run_sceneflow_bench`: scene-flow accuracy and the motorcycle check;
- :func:`.paper_bench.run_paper_bench`: Tables 2-4 (columns in :mod:`.paper_columns`,
  report in :mod:`.paper_tables`);
- :func:`.kernels_figure.write_kernel_figure`: the paper's Fig. 3.

:mod:`.metrics` holds PSNR, SSIM, endpoint and disparity errors.
"""
