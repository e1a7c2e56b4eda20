# Reference answers of R's `shapes` (Dryden) and `vegan` for the ADHD-200 corpus callosum outlines
# of the shared data: Procrustes PCA variance shares, Procrustes ANOVA (adonis2 on the Procrustes
# tangent coordinates) of diagnosis, and Goodall's F test of TD against ADHD-combined.
# Run from the repository root:  Rscript data/reference/r_shapes/adhd200.R
# Reads $SHAPELIB_DATA_DIR/adhd200/{ADHD-200.Rdata,clinical_info.csv}; writes data/reference/r_shapes/*.csv.
suppressMessages({library(shapes); library(vegan)})
dir <- Sys.getenv("SHAPELIB_DATA_DIR")
load(file.path(dir, "adhd200", "ADHD-200.Rdata"))
clin <- read.csv(file.path(dir, "adhd200", "clinical_info.csv"))
x <- sapply(chains, function(ch) { a <- as.matrix(ch$plg.chains[[1]]); a[-nrow(a), ] }, simplify = "array")
stopifnot(dim(x)[1] == 50, dim(x)[3] == nrow(clin))
out <- "data/reference/r_shapes"
gpa <- procGPA(x, scale = TRUE, tangentcoords = "partial")
pcs <- data.frame(component = seq_len(10), percent = gpa$percent[1:10])
write.csv(pcs, file.path(out, "pca.csv"), row.names = FALSE)
# tangent coordinates (partial Procrustes, at the mean), one row per specimen
tan <- t(gpa$tan)
diagnosis <- factor(clin$phenotype)
set.seed(1)
a <- adonis2(dist(tan) ~ diagnosis, permutations = 999, method = "euclidean")
anova <- data.frame(term = c("diagnosis", "Residual", "Total"), df = a$Df, sum_of_squares = a$SumOfSqs,
                    r2 = a$R2, F = a$F, p_value = a[["Pr(>F)"]])
write.csv(anova, file.path(out, "anova.csv"), row.names = FALSE)
td <- x[, , clin$phenotype == 0]
comb <- x[, , clin$phenotype == 1]
g <- testmeanshapes(td, comb, resamples = 0, replace = FALSE, scale = TRUE)
goodall <- data.frame(statistic = "Goodall F", F = g$G, p_value = g$G.table.pvalue, n_td = dim(td)[3],
                      n_comb = dim(comb)[3])
write.csv(goodall, file.path(out, "goodall.csv"), row.names = FALSE)
writeLines(c(R.version.string, paste("shapes", packageVersion("shapes")), paste("vegan", packageVersion("vegan"))),
           file.path(out, "versions.txt"))
