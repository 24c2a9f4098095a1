" RSSM specifications
autocmd BufRead,BufNewFile *.rssm setfiletype rssm
