"""Developer tools of VPL GI, not shipped with the add-on (excluded from the extension zip):
the error-against-time report, OBJ benchmark scenes and image error metrics."""
