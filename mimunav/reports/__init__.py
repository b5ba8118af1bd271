"""Reports a person reads: markdown tables with figures, generated into `reports/`."""
