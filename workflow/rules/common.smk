# Shared settings of the rules: where results go and which config file the run uses.
CONFIG_PATH = workflow.configfiles[-1]
RESULTS = f"results/{config['campaign']['name']}"
LOGS = f"{RESULTS}/logs"
